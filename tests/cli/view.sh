# psys view, driven like a new user would (docs/cli.md "psys view"): under a
# private Xvfb, xdotool opens an empty scene, clicks three particles A, B, C,
# drags two springs (A-B, B-C), pins A with P, drags C with the mouse spring
# (right button) and saves with Ctrl+S. The saved scene must hold exactly
# those three particles, two springs and one pin (no mouse spring), C must
# have followed the mouse spring, the file must load in `psys run`, and Q
# must end the viewer with status 0.
#
# Timing: the machine may be loaded, so every wait polls for its condition
# with a generous limit; the viewer handles X events strictly in order, so
# clicks and keys need no pauses between them.
# shellcheck disable=SC2034  # RC is read by the helpers in lib.sh
HERE=$(cd "$(dirname "$0")" && pwd)
. "$HERE/lib.sh"
. "$HERE/view_x.sh"

for tool in xdotool jq xwininfo; do
    if ! command -v "$tool" >/dev/null 2>&1; then
        fail "$tool is not installed (make deps installs it)"
        finish
    fi
done

# Empty 2-D scene: the view is 4 units high around the origin, so in a
# 960x720 window pixel (px, py) is the point ((px - 480)/180, (360 - py)/180).
"$PSYS" view --save saved.json --size 960x720 >view.out 2>view.err </dev/null &
VIEW_PID=$!
find_window() { WID=$(xdotool search --name '^psys' 2>/dev/null | head -n 1); [ -n "$WID" ] || ! kill -0 "$VIEW_PID" 2>/dev/null; }
WID=
if ! wait_for 60 find_window || [ -z "$WID" ]; then
    fail "no window titled psys... appeared (stderr: $(head -c 600 view.err))"
    kill "$VIEW_PID" 2>/dev/null
    finish
fi
ok
viewable() { xwininfo -id "$WID" 2>/dev/null | grep -q 'IsViewable'; }
check "the window is mapped" wait_for 60 viewable
check "the window title starts with psys" bash -c "xdotool getwindowname $WID | grep -q '^psys'"

x() { xdotool "$@"; }
# A (300,300), B (500,300), C (400,450): three clicks on empty space.
x mousemove --sync --window "$WID" 300 300 click 1 \
  mousemove --sync --window "$WID" 500 300 click 1 \
  mousemove --sync --window "$WID" 400 450 click 1
# Springs A-B and B-C: left drags from one particle to another.
x mousemove --sync --window "$WID" 300 300 mousedown 1 mousemove --sync --window "$WID" 400 310 \
  mousemove --sync --window "$WID" 500 300 mouseup 1
x mousemove --sync --window "$WID" 500 300 mousedown 1 mousemove --sync --window "$WID" 450 380 \
  mousemove --sync --window "$WID" 400 450 mouseup 1
# Pin A: P with the pointer over it.
x mousemove --sync --window "$WID" 300 300 key p
# Drag C with the mouse spring toward (460, 560) and hold it there a while.
x mousemove --sync --window "$WID" 400 450 mousedown 3 mousemove --sync --window "$WID" 430 500 \
  mousemove --sync --window "$WID" 460 560
sleep 2
x mouseup 3
# The window really shows something (an X screenshot of it, not just GL's buffer).
if command -v import >/dev/null 2>&1 && [ -n "${PSYS_PNG_PROBE:-}" ]; then
    import -window "$WID" shown.png 2>/dev/null
    "$PSYS_PNG_PROBE" shown.png 300 300 >probe.txt 2>&1
    nonbg=$(awk '$1 == "nonbackground" { print $2 }' probe.txt)
    check "the window shows the particles, springs and HUD ($nonbg pixels)" test "${nonbg:-0}" -gt 500
fi
x key ctrl+s
saved() { [ -s saved.json ]; }
check "Ctrl+S writes saved.json" wait_for 60 saved
x key q
exited() { ! kill -0 "$VIEW_PID" 2>/dev/null; }
if wait_for 60 exited; then
    wait "$VIEW_PID"
    expect_eq 0 "$?" "Q ends the viewer with status 0"
else
    fail "the viewer did not exit after Q"
    kill "$VIEW_PID" 2>/dev/null
fi
check "the viewer says where it saved" grep -q '^saved saved.json: 3 particles, 2 springs$' view.out
# psys's own messages are failures; anything else (a GL driver's notes) is shown
if grep -q '^psys:' view.err; then
    fail "the viewer printed an error: $(grep '^psys:' view.err | head -c 600)"
elif [ -s view.err ]; then
    echo "view.sh: note: the viewer's stderr: $(head -c 600 view.err)"
fi

if [ -s saved.json ]; then
    expect_eq 2 "$(jq '.dim' saved.json)" "saved: dim"
    expect_eq 3 "$(jq '.particles | length' saved.json)" "saved: three particles"
    expect_eq 2 "$(jq '[.forces[] | select(.type == "spring")] | length' saved.json)" "saved: two springs"
    expect_eq 2 "$(jq '.forces | length' saved.json)" "saved: no other forces (no mouse spring, no gravity)"
    expect_eq "0-1 1-2" "$(jq -r '[.forces[] | "\(.a)-\(.b)"] | join(" ")' saved.json)" "saved: springs A-B and B-C"
    expect_eq "true false false" "$(jq -r '[.particles[] | .fixed // false] | map(tostring) | join(" ")' saved.json)" \
        "saved: only A is pinned"
    # A is pinned where it was clicked: (300,300) -> (-1, 1/3).
    expect_eq "-1 0.333333" "$(jq -r '.particles[0].x | map(. * 1000000 | round / 1000000) | map(tostring) | join(" ")' saved.json)" \
        "saved: A at the clicked point"
    # Rest lengths are the distances when joined: 200 px = 10/9, and B-C 180.28 px.
    expect_eq "1.111111 1.001542" "$(jq -r '[.forces[].rest * 1000000 | round / 1000000] | map(tostring) | join(" ")' saved.json)" \
        "saved: rest lengths are the distances at joining"
    # C was made at (400,450) -> (-0.444, -0.5); the mouse spring pulled it
    # toward (460,560) -> (-0.111, -1.111).
    moved=$(jq '.particles[2].x as $c | (($c[0] + 0.4444444) * ($c[0] + 0.4444444) + ($c[1] + 0.5) * ($c[1] + 0.5)) | sqrt > 0.05' saved.json)
    expect_eq true "$moved" "saved: C followed the mouse spring (x = $(jq -c '.particles[2].x' saved.json))"
    psys check saved.json
    expect_rc 0 "psys check on the saved scene"
    check "check: 3 particles" grep -qx 'particles: 3' out.txt
    check "check: 2 springs" grep -qx 'springs: 2' out.txt
    check "check: 1 fixed" grep -qx 'fixed: 1' out.txt
    psys run saved.json --steps 100 --out run.csv --quiet
    expect_rc 0 "psys run on the saved scene"
    expect_eq 304 "$(wc -l <run.csv | tr -d ' ')" "psys run writes 101 frames of 3 particles"
fi

# Second session on the saved scene, paused: G (gravity on), Delete on B
# (B and both its springs go), Ctrl+Z (they come back), Delete on the A-B
# spring, M on C (a circle motor), Ctrl+S to --save edited.json. Where the
# particles are comes from a screenshot at the same window size: the
# camera frames the scene the same way.
if [ -s saved.json ]; then
    "$PSYS" view saved.json --paused --size 960x720 --frames 1 --screenshot where.png >where.txt 2>where.err </dev/null
    expect_eq 0 "$?" "screenshot of the saved scene"
    px() { awk -v i="$1" '$1 == "particle" && $2 == i { print $3, $4 }' where.txt; }
    read -r AX AY <<<"$(px 0)"
    read -r BX BY <<<"$(px 1)"
    read -r CX CY <<<"$(px 2)"
    # a point on the A-B spring, a third of the way from A (away from both ends)
    SX=$(((2 * AX + BX) / 3))
    SY=$(((2 * AY + BY) / 3))
    "$PSYS" view saved.json --paused --size 960x720 --save edited.json >view2.out 2>view2.err </dev/null &
    VIEW_PID=$!
    WID=
    if wait_for 60 find_window && [ -n "$WID" ] && wait_for 60 viewable; then
        # G held for 0.6 s: the X server (view_x.sh: first repeat after
        # 100 ms, the next after 30 s) repeats it exactly once, and a held
        # toggle key must act once (docs/cli.md): gravity ends up on, not off.
        x mousemove --sync --window "$WID" 20 700 keydown g
        sleep 0.6
        x keyup g
        x mousemove --sync --window "$WID" "$BX" "$BY" key Delete
        x key ctrl+z
        x mousemove --sync --window "$WID" "$SX" "$SY" key Delete
        x mousemove --sync --window "$WID" "$CX" "$CY" key m
        x key ctrl+s
        edited() { [ -s edited.json ]; }
        check "Ctrl+S writes edited.json (--save)" wait_for 60 edited
        x key Escape
        if wait_for 60 exited; then
            wait "$VIEW_PID"
            expect_eq 0 "$?" "Esc ends the viewer with status 0"
        else
            fail "the viewer did not exit after Esc"
            kill "$VIEW_PID" 2>/dev/null
        fi
    else
        fail "second session: no window (stderr: $(head -c 600 view2.err))"
        kill "$VIEW_PID" 2>/dev/null
    fi
    if [ -s edited.json ]; then
        expect_eq 3 "$(jq '.particles | length' edited.json)" "edited: undo brought B back"
        expect_eq "1-2" "$(jq -r '[.forces[] | select(.type == "spring") | "\(.a)-\(.b)"] | join(" ")' edited.json)" \
            "edited: only the B-C spring is left"
        expect_eq 1 "$(jq '[.forces[] | select(.type == "gravity")] | length' edited.json)" "edited: G turned gravity on"
        expect_eq "true" "$(jq '.particles[0].fixed' edited.json)" "edited: A is still pinned"
        expect_eq "circle" "$(jq -r '.particles[2].control.type' edited.json)" "edited: M made C a circle motor"
        psys run edited.json --steps 50 --quiet
        expect_rc 0 "psys run on the edited scene"
    fi
fi
finish
