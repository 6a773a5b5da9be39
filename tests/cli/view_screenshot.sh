# psys view --screenshot (docs/cli.md "psys view"): the viewer draws example
# scenes with OpenGL under a private Xvfb; the PNG has the asked size and
# the pixel under every particle the viewer reports is not background, in
# 2-D and in 3-D (perspective). Bad options are refused before any window
# opens. Needs tests/tools/png_probe ($PSYS_PNG_PROBE, tests/view.cmake).
# shellcheck disable=SC2034  # RC is read by the helpers in lib.sh
HERE=$(cd "$(dirname "$0")" && pwd)
. "$HERE/lib.sh"

PROBE=${PSYS_PNG_PROBE:-}
if [ -z "$PROBE" ] || [ ! -x "$PROBE" ]; then
    echo "view_screenshot.sh: set PSYS_PNG_PROBE to the png_probe helper (tests/view.cmake does)" >&2
    exit 2
fi

# Usage errors come before any window (no X server needed).
psys view --frames 0
expect_rc 2 "--frames 0"
expect_stderr 'psys: --frames must be a whole number >= 1 (got 0)' "--frames 0"
psys view --bogus
expect_rc 2 "unknown option"
expect_stderr 'psys: view: unknown option --bogus (see psys --help)' "unknown option"
psys view missing.json
expect_rc 2 "missing scene"
expect_stderr_has "missing.json" "missing scene"
psys view --integrator nope
expect_rc 2 "unknown integrator"
psys view --screenshot
expect_rc 2 "--screenshot without a value"
expect_stderr 'psys: --screenshot needs a value (see psys --help)' "--screenshot without a value"
psys --help
for flag in --save --screenshot --frames --paused --size --controls; do
    check "--help mentions view's $flag" grep -q -e "$flag\\b" out.txt
done

. "$HERE/view_x.sh"

# shot SCENE WxH NAME: screenshot after a few frames, paused at the start state.
shot() {
    "$PSYS" view "$1" --paused --size "$2" --frames 3 --screenshot "$3.png" >"$3.txt" 2>"$3.err" </dev/null
    RC=$?
}

for scene in pendulum hanging-chain bouncing-balls cloth-small soft-block; do
    shot "$SRC/examples/$scene.json" 640x480 "$scene"
    expect_rc 0 "$scene: screenshot"
    if grep -q '^psys:' "$scene.err"; then fail "$scene: $(grep '^psys:' "$scene.err" | head -c 400)"; fi
    check "$scene: the viewer reports the picture" grep -qx "screenshot $scene.png 640 480" "$scene.txt"
    # every particle inside the picture
    awk '$1 == "particle" && $3 >= 0 && $3 < 640 && $4 >= 0 && $4 < 480 { print $3, $4 }' "$scene.txt" >inside.txt
    n=$(grep -c "^particle " "$scene.txt")
    ni=$(wc -l <inside.txt | tr -d ' ')
    check "$scene: particles reported ($n, $ni in the picture)" test "$ni" -gt 0
    # shellcheck disable=SC2046  # the coordinates are words on purpose
    "$PROBE" "$scene.png" $(cat inside.txt) >probe.txt 2>&1
    expect_eq "size 640 480" "$(grep '^size' probe.txt)" "$scene: picture size"
    bg=$(awk '$1 == "background" { print $2, $3, $4 }' probe.txt)
    # the pixel under each particle differs from the background
    bad=$(awk -v bg="$bg" 'BEGIN { split(bg, b, " ") }
        $1 == "pixel" { d = 0; for (k = 4; k <= 6; k++) { e = $k - b[k - 3]; if (e < 0) e = -e; if (e > d) d = e }
                        if (d <= 24) { print $2 "," $3; n++ } }
        END { }' probe.txt | head -n 5)
    expect_eq "" "$bad" "$scene: background pixels where particles are (bg $bg)"
    nonbg=$(awk '$1 == "nonbackground" { print $2 }' probe.txt)
    check "$scene: something is drawn ($nonbg pixels)" test "${nonbg:-0}" -gt 200
done
# Planes are drawn: bouncing-balls' floor and walls shade part of the picture.
"$PROBE" bouncing-balls.png >probe.txt 2>&1
nonbg=$(awk '$1 == "nonbackground" { print $2 }' probe.txt)
check "bouncing-balls: the planes are shaded ($nonbg pixels)" test "${nonbg:-0}" -gt 20000

# An empty scene with --frames and no screenshot: opens, runs, exits 0.
psys view --frames 5
expect_rc 0 "empty scene, --frames 5"
finish
