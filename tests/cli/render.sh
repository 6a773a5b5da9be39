# Headless rendering (docs/cli.md "Pictures and video"): psys run --render
# writes out.png (last frame), frames/%04d.png, out.gif and out.mp4 at the
# asked --size, frames at t0 + k/fps; pixels land where the particles are;
# a run that cannot start creates nothing; nothing is printed off a terminal.
#
# Needs tests/tools/png_probe (path in $PSYS_PNG_PROBE, set by
# tests/render.cmake); ffprobe checks run where ffmpeg is installed.
# shellcheck disable=SC2034  # RC is read by the helpers in lib.sh
. "$(dirname "$0")/lib.sh"

PROBE=${PSYS_PNG_PROBE:-}
if [ -z "$PROBE" ] || [ ! -x "$PROBE" ]; then
    echo "render.sh: set PSYS_PNG_PROBE to the png_probe helper (tests/render.cmake does)" >&2
    exit 2
fi
HAVE_FFMPEG=0
if command -v ffmpeg >/dev/null 2>&1 && command -v ffprobe >/dev/null 2>&1; then
    HAVE_FFMPEG=1
else
    echo "render.sh: ffmpeg/ffprobe not installed: MP4 and ffmpeg GIF checks skipped"
fi

# probe FILE [X Y]...: png_probe output in probe.txt; status of png_probe.
probe() { "$PROBE" "$@" >probe.txt 2>&1; }
# probe_field KEY [N]: field N (default 2) of the probe.txt line starting with KEY.
probe_size() { awk '$1 == "size" { print $2 "x" $3 }' probe.txt; }
probe_nonbg() { awk '$1 == "nonbackground" { print $2 }' probe.txt; }
probe_pixel() { awk -v x="$1" -v y="$2" '$1 == "pixel" && $2 == x && $3 == y { print $4, $5, $6 }' probe.txt; }

# expect_png FILE WxH MIN_NONBG LABEL: a readable PNG of that size with at
# least MIN_NONBG pixels that are not background.
expect_png() {
    if ! probe "$1"; then
        fail "$4: $1 is not a readable PNG: $(cat probe.txt)"
        return
    fi
    expect_eq "$2" "$(probe_size)" "$4: size"
    local n
    n=$(probe_nonbg)
    if [ "${n:-0}" -ge "$3" ]; then ok; else fail "$4: only ${n:-0} non-background pixels (want >= $3)"; fi
}

# frame_count FILE: video frames ffprobe decodes.
frame_count() {
    ffprobe -v error -count_frames -select_streams v:0 -show_entries stream=nb_read_frames -of csv=p=0 "$1" 2>&1
}

dir_listing() { find . -mindepth 1 ! -name out.txt ! -name err.txt ! -name probe.txt | LC_ALL=C sort; }

# cannot_start LABEL MESSAGE ARGS...: exit 2, exactly "psys: MESSAGE", no file created.
cannot_start() {
    local label=$1 msg=$2
    shift 2
    local before after
    before=$(dir_listing)
    psys "$@"
    after=$(dir_listing)
    expect_rc 2 "$label"
    expect_stderr "psys: $msg" "$label"
    if [ "$before" = "$after" ]; then
        ok
    else
        fail "$label: files were created: $(printf '%s\n' "$after" | grep -vxF -e "$before" | tr '\n' ' ')"
    fi
}

# A 2-D scene at rest with no gravity: a fixed anchor at (0, 0), a free
# particle at (1, 0) on a spring at its rest length, and a floor at y = -1.
cat >still.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.01, "duration": 1,
 "particles": [{"id": "a", "x": [0, 0], "fixed": true}, {"id": "b", "x": [1, 0], "mass": 1}],
 "forces": [{"type": "spring", "a": "a", "b": "b", "ks": 10}],
 "planes": [{"point": [0, -1], "normal": [0, 1]}]}
EOF
# A 2-D pendulum that moves.
cat >swing.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.001, "duration": 1,
 "particles": [{"id": "p", "x": [0, 0], "fixed": true}, {"id": "b", "x": [1, 0], "mass": 1}],
 "forces": [{"type": "gravity"}, {"type": "spring", "a": "p", "b": "b", "ks": 1000, "kd": 0.5}]}
EOF
# A 3-D cloth over a floor.
cat >cloth.json <<'EOF'
{"psys": 1, "dim": 3, "dt": 0.002, "duration": 0.5,
 "structures": [{"type": "cloth", "id": "c", "origin": [0, 0, 0], "size": [6, 6], "spacing": 0.1,
                 "mass": 0.01, "ks": 300, "kd": 0.05, "axes": [[1, 0, 0], [0, 0, 1]], "pin": [[0, 0], [5, 0]]}],
 "forces": [{"type": "gravity"}],
 "planes": [{"point": [0, -0.8, 0], "normal": [0, 1, 0]}]}
EOF

# ---------------------------------------------------------------- a picture where the particles are

# A fixed camera: centre (0, 0), 4 units high in a 200×200 picture: 50 px per
# unit, so (0, 0) is pixel (100, 100) and (1, 0) is pixel (150, 100); the
# radius 0.2 is 10 px.
psys run still.json --render still.png --size 200x200 --camera center=0:0,extent=4 --radius 0.2
expect_rc 0 "still.png"
expect_stderr_empty "still.png: nothing printed off a terminal"
expect_png still.png 200x200 300 "still.png"
probe still.png 150 100 100 100 20 190 100 40 100 170
read -r r g b <<<"$(probe_pixel 150 100)"
check "free particle drawn at (1, 0) = pixel (150, 100) in blue (got $r $g $b)" \
    test "${b:-0}" -gt $((${r:-0} + 40))
read -r r g b <<<"$(probe_pixel 100 100)"
check "fixed particle drawn at (0, 0) = pixel (100, 100) in dark grey (got $r $g $b)" \
    test "${r:-255}" -lt 100 -a "${g:-255}" -lt 100 -a "${b:-255}" -lt 100
read -r r g b <<<"$(probe_pixel 100 40)"
bg=$(awk '$1 == "background" { print $2, $3, $4 }' probe.txt)
expect_eq "$bg" "$r $g $b" "empty space above the particles is background"
read -r r g b <<<"$(probe_pixel 100 170)"
check "below the floor line (y = -1 is pixel row 150) is shaded (got $r $g $b, background $bg)" \
    test "$r $g $b" != "$bg"
read -r r g b <<<"$(probe_pixel 125 100)"
check "the spring between them is drawn (pixel (125, 100): $r $g $b)" test "$r $g $b" != "$bg"

# Automatic framing, default size 800x600, last frame of a moving scene.
psys run swing.json --render swing.png
expect_rc 0 "swing.png"
expect_png swing.png 800x600 500 "swing.png (default size, automatic camera)"
# The scene's output.render means the same as the flag.
sed 's/"duration": 1,/"duration": 1, "output": {"render": "scene.png", "radius": 0.05},/' swing.json >scene-out.json
psys run scene-out.json --size 160x120
expect_rc 0 "output.render"
expect_png scene.png 160x120 50 "output.render (scene key)"
# 3-D: default perspective, and an orthographic view from above.
psys run cloth.json --render cloth.png --size 320x240
expect_rc 0 "3-D cloth"
expect_png cloth.png 320x240 1000 "3-D cloth, perspective"
psys run cloth.json --render top.png --size 320x240 --camera ortho,az=0,el=90
expect_rc 0 "3-D cloth from above"
expect_png top.png 320x240 1000 "3-D cloth, orthographic from above"
psys run cloth.json --render fixed.png --size 320x240 --camera perspective,az=-40,el=35,fov=50,center=0.25:-0.3:0.25,extent=1.5,up=y
expect_rc 0 "3-D cloth, fixed camera"
expect_png fixed.png 320x240 500 "3-D cloth, fixed camera"
psys run cloth.json --render start.png --size 320x240 --camera fit=start,zoom=0.8
expect_rc 0 "fit=start"
expect_png start.png 320x240 500 "fit=start, zoom"

# An existing picture is replaced only when the new one is complete.
sentinel old.png
psys run still.json --render old.png --size 64x48
expect_rc 0 "over an existing PNG"
expect_png old.png 64x48 1 "over an existing PNG"
expect_no_tmp "PNG"

# ---------------------------------------------------------------- frame sequences and timing

mkdir frames
psys run swing.json --render 'frames/f%04d.png' --size 96x64 --fps 10
expect_rc 0 "frame pattern"
expect_stderr_empty "frame pattern"
expect_eq "f0000.png f0001.png f0002.png f0003.png f0004.png f0005.png f0006.png f0007.png f0008.png f0009.png f0010.png" \
    "$(cd frames && ls | tr '\n' ' ' | sed 's/ $//')" "1 s at 10 fps: frames 0..10"
bad=0
for f in frames/*.png; do "$PROBE" "$f" >/dev/null 2>&1 || bad=1; done
expect_eq 0 "$bad" "every frame is a readable PNG"
expect_png frames/f0007.png 96x64 20 "a frame of the sequence"
expect_no_tmp "frame pattern" frames
# Frames are taken at t0 + k/fps, independent of dt and --every: 0.95 s at
# 10 fps is frames 0..9; steps of 0.25 s longer than 1/fps repeat states.
mkdir f2 f3 f4
psys run swing.json --render 'f2/%d.png' --size 32x32 --fps 10 --duration 0.95 --every 7
expect_eq 10 "$(ls f2 | wc -l)" "0.95 s at 10 fps: 10 frames"
expect_exists f2/9.png "unpadded frame numbers"
psys run swing.json --render 'f3/%03d.png' --size 32x32 --fps 10 --dt 0.25 --integrator euler
expect_eq 11 "$(ls f3 | wc -l)" "dt 0.25 > 1/fps: still 11 frames for 1 s"
psys run swing.json --render 'f4/%03d.png' --size 32x32 --fps 2.5 --steps 1000
expect_eq 3 "$(ls f4 | wc -l)" "fractional fps 2.5 over 1 s: frames at 0, 0.4, 0.8"
expect_exists f4/002.png "zero-padded frame numbers"

# A long render on a terminal shows the progress bar (off a terminal nothing
# is printed: checked above with expect_stderr_empty).
if command -v script >/dev/null 2>&1; then
    mkdir tty
    # The bar appears after 2 s: the render must take longer than that even on
    # a fast machine (about 5 s here).
    script -qec "'$PSYS' run swing.json --render 'tty/%03d.png' --size 1000x1000 --fps 40 --duration 5 --camera fit=start" \
        /dev/null >tty.txt 2>&1 </dev/null
    check "progress bar on a terminal during a long render (got: $(tr '\r' '\n' <tty.txt | grep -m1 . | head -c 120))" \
        grep -q '%  step [0-9]* *eta' tty.txt
    expect_eq 201 "$(ls tty | wc -l | tr -d ' ')" "the render on a terminal wrote every frame"
fi

# ---------------------------------------------------------------- GIF

# The built-in encoder (no ffmpeg): a GIF89a with one image per frame.
PSYS_FFMPEG=/nonexistent/ffmpeg psys run swing.json --render builtin.gif --size 120x90 --fps 10
expect_rc 0 "built-in GIF"
check "built-in GIF starts with GIF89a" sh -c 'head -c 6 builtin.gif | grep -q GIF89a'
check "built-in GIF ends with the trailer" sh -c 'tail -c 1 builtin.gif | od -An -tx1 | grep -q 3b'
check "built-in GIF has 11 images" test "$(od -An -v -tx1 builtin.gif | tr -s ' \n' ' ' | grep -o '21 f9 04' | wc -l)" -eq 11
if [ "$HAVE_FFMPEG" = 1 ]; then
    expect_eq 11 "$(frame_count builtin.gif)" "ffprobe decodes the built-in GIF's 11 frames"
    psys run swing.json --render ff.gif --size 120x90 --fps 10
    expect_rc 0 "GIF through ffmpeg"
    expect_stderr_empty "GIF through ffmpeg"
    expect_eq 11 "$(frame_count ff.gif)" "GIF through ffmpeg: 11 frames"
    expect_eq "120,90" "$(ffprobe -v error -select_streams v:0 -show_entries stream=width,height -of csv=p=0 ff.gif)" \
        "GIF size"
fi

# ---------------------------------------------------------------- MP4

if [ "$HAVE_FFMPEG" = 1 ]; then
    psys run swing.json --render swing.mp4 --size 160x120 --fps 10
    expect_rc 0 "MP4"
    expect_stderr_empty "MP4"
    expect_eq 11 "$(frame_count swing.mp4)" "MP4: 1 s at 10 fps is 11 frames"
    expect_eq "h264,160,120,yuv420p" \
        "$(ffprobe -v error -select_streams v:0 -show_entries stream=codec_name,pix_fmt,width,height -of csv=p=0 swing.mp4)" \
        "MP4: H.264, yuv420p, 160x120"
    psys run cloth.json --render cloth.mp4 --size 320x240
    expect_rc 0 "MP4 of a 3-D cloth at 30 fps"
    expect_eq 16 "$(frame_count cloth.mp4)" "MP4: 0.5 s at 30 fps is 16 frames"
    expect_no_tmp "MP4"
    # Interrupted: the video keeps the frames so far and is complete.
    "$PSYS" run swing.json --duration 1000 --render long.mp4 --size 64x48 --fps 50 --camera fit=start \
        >out.txt 2>err.txt </dev/null &
    pid=$!
    wait_caught "$pid" INT && sleep 1.5
    kill -INT "$pid"
    wait "$pid"
    RC=$?
    expect_rc 130 "MP4 interrupted by SIGINT"
    n=$(frame_count long.mp4)
    check "interrupted MP4 is a complete video with frames (got $n)" test "${n:-0}" -gt 1 2>/dev/null
    expect_no_tmp "interrupted MP4"
fi

# An ffmpeg that reads the first frame (32x32 BGRA: 4,096 bytes) and fails:
# the 30 frames (120 KB) overfill the pipe, so a later frame cannot be
# written for certain, after one was. The run exits 1 and neither replaces
# the video that was there nor leaves an empty one or a temporary file.
printf '#!/bin/sh\nhead -c 4096 >/dev/null\nexit 1\n' >failing-ffmpeg
chmod +x failing-ffmpeg
sentinel kept.mp4
PSYS_FFMPEG=$PWD/failing-ffmpeg psys run swing.json --render kept.mp4 --size 32x32
expect_rc 1 "MP4 whose ffmpeg fails"
expect_untouched kept.mp4 "MP4 whose ffmpeg fails"
PSYS_FFMPEG=$PWD/failing-ffmpeg psys run swing.json --render new.mp4 --size 32x32
expect_rc 1 "new MP4 whose ffmpeg fails"
check "no new.mp4 after ffmpeg failed" test ! -e new.mp4
expect_no_tmp "MP4 whose ffmpeg fails"

# A radius of 1e300 (the markers cover the picture) renders at once; cairo's
# arcs of that radius took minutes and ignored SIGTERM meanwhile.
timeout 120 "$PSYS" run swing.json --render huge.png --size 64x64 --radius 1e300 >out.txt 2>err.txt
RC=$?
expect_rc 0 "--radius 1e300"
expect_exists huge.png "--radius 1e300"

# Without ffmpeg an MP4 cannot be made: the run does not start.
export PSYS_FFMPEG=/nonexistent/ffmpeg
cannot_start "MP4 without ffmpeg" \
    '--render x.mp4: .mp4 needs ffmpeg, which was not found at $PSYS_FFMPEG (install ffmpeg, or render a .gif or PNG frames such as frames/%04d.png)' \
    run swing.json --render x.mp4 --out x.csv
cannot_start "MP4 without ffmpeg (again, with an energy file)" \
    '--render y.mp4: .mp4 needs ffmpeg, which was not found at $PSYS_FFMPEG (install ffmpeg, or render a .gif or PNG frames such as frames/%04d.png)' \
    run swing.json --render y.mp4 --energy y.csv
unset PSYS_FFMPEG

# ---------------------------------------------------------------- runs that cannot start

sentinel keep.png
cannot_start "bad --size" '--size: must be WIDTHxHEIGHT, each from 16 to 8192 (got 10x10)' \
    run swing.json --render keep.png --size 10x10 --out a.csv
cannot_start "--size without x" '--size: must be WIDTHxHEIGHT, each from 16 to 8192 (got 800)' \
    run swing.json --render keep.png --size 800
cannot_start "--size with junk" '--size: must be WIDTHxHEIGHT, each from 16 to 8192 (got 80x60px)' \
    run swing.json --render keep.png --size 80x60px
cannot_start "--size too large" '--size: must be WIDTHxHEIGHT, each from 16 to 8192 (got 9000x600)' \
    run swing.json --render keep.png --size 9000x600
cannot_start "odd MP4 size" '--size: .mp4 (H.264, yuv420p) needs an even width and height (got 161x120)' \
    run swing.json --render keep.mp4 --size 161x120
cannot_start "--fps 0" '--fps: must be a number > 0 and at most 1000 (got 0)' run swing.json --render keep.png --fps 0
cannot_start "--fps -5" '--fps: must be a number > 0 and at most 1000 (got -5)' run swing.json --render keep.png --fps -5
cannot_start "--fps abc" '--fps: must be a number > 0 and at most 1000 (got abc)' run swing.json --render keep.png --fps abc
cannot_start "--fps huge" '--fps: must be a number > 0 and at most 1000 (got 5000)' run swing.json --render keep.png --fps 5000
cannot_start "--fps without --render" '--fps: only with --render (or output.render)' run swing.json --fps 10 --out a.csv
cannot_start "--camera without --render" '--camera: only with --render (or output.render)' run swing.json --camera ortho
cannot_start "--size without --render" '--size: only with --render or --plot (or output.render)' run swing.json --size 80x60
cannot_start "camera zoom above its bound" '--camera: zoom= must be a number > 0 and at most 1e6 (got 1e12)' \
    run swing.json --render keep.png --camera zoom=1e12
cannot_start "unknown camera item" \
    '--camera: unknown item "sideways" (known: ortho, perspective, az=DEG, el=DEG, fov=DEG, up=x|y|z, center=X:Y[:Z], extent=L, zoom=F, fit=run|start)' \
    run cloth.json --render keep.png --camera sideways
cannot_start "camera az in 2-D" '--camera: az= is only for 3-D scenes' run swing.json --render keep.png --camera az=30
cannot_start "camera perspective in 2-D" '--camera: perspective is only for 3-D scenes' \
    run swing.json --render keep.png --camera perspective
cannot_start "camera el out of range" '--camera: el= must be a number of degrees from -90 to 90 (got 91)' \
    run cloth.json --render keep.png --camera el=91
cannot_start "camera fov" '--camera: fov= must be a number of degrees from 1 to 170 (got 0)' \
    run cloth.json --render keep.png --camera fov=0
cannot_start "camera center" '--camera: center= must be 3 numbers separated by colons, e.g. 0:1.5:0 (got 1:2)' \
    run cloth.json --render keep.png --camera center=1:2
cannot_start "camera extent" '--camera: extent= must be a number > 0 (got -1)' \
    run cloth.json --render keep.png --camera extent=-1
cannot_start "camera up" '--camera: up= must be x, y or z (got w)' run cloth.json --render keep.png --camera up=w
cannot_start "camera empty item" '--camera: empty item in "ortho,,az=3"' run cloth.json --render keep.png --camera ortho,,az=3
cannot_start "--radius" '--radius: must be a finite number > 0 (got 0)' run swing.json --render keep.png --radius 0
cannot_start "unknown picture format" \
    '--render keep.avi: unknown picture format (got ".avi"; use .png, a frame pattern such as frames/%04d.png, .gif or .mp4)' \
    run swing.json --render keep.avi --out a.csv
cannot_start "frame pattern with two numbers" \
    '--render f/%d_%d.png: a frame pattern needs exactly one %d or %0Nd (N up to 18), e.g. frames/%04d.png' \
    run swing.json --render 'f/%d_%d.png'
cannot_start "frame pattern not PNG" '--render f%03d.gif: frame patterns must end in .png (got ".gif")' \
    run swing.json --render 'f%03d.gif'
cannot_start "frame number in a directory" \
    '--render run%d/f.png: the frame number must be in the file name, not in a directory name' \
    run swing.json --render 'run%d/f.png'
cannot_start "frames into a missing directory" '--render nodir/%04d.png: cannot create: No such file or directory' \
    run swing.json --render 'nodir/%04d.png' --out a.csv --energy e.csv --checkpoint ck.json
cannot_start "PNG into a missing directory" '--render nodir/a.png: cannot create: No such file or directory' \
    run swing.json --render nodir/a.png --out a.csv
cannot_start "render and plot to one file" \
    'x.png: the trajectory, energy, checkpoint, render and plot files must be different files' \
    run swing.json --render x.png --plot x.png
cannot_start "render and checkpoint to one file" \
    'k.png: the trajectory, energy, checkpoint, render and plot files must be different files' \
    run swing.json --render k.png --checkpoint k.png
sed 's/"duration": 1,/"duration": 1, "output": {"render": "scene.avi"},/' swing.json >bad-render.json
cannot_start "output.render with an unknown format" \
    'output.render scene.avi: unknown picture format (got ".avi"; use .png, a frame pattern such as frames/%04d.png, .gif or .mp4)' \
    run bad-render.json
sed 's/"duration": 1,/"duration": 1, "output": {"radius": -1},/' swing.json >bad-radius.json
cannot_start "output.radius <= 0" 'bad-radius.json: output.radius: must be > 0 (got -1)' run bad-radius.json --render r.png
expect_untouched keep.png "runs that could not start"

# ---------------------------------------------------------------- the README's pictures

# Every example has its picture, drawn by scripts/render-examples.sh with
# psys, in docs/images/ and shown in README.md.
if [ -n "$SRC" ]; then
    for ex in "$SRC"/examples/*.json; do
        name=$(basename "$ex" .json)
        img=$SRC/docs/images/$name.png
        if [ ! -f "$img" ]; then
            fail "examples/$name.json has no picture docs/images/$name.png (run scripts/render-examples.sh build/psys)"
            continue
        fi
        expect_png "$img" 480x360 50 "docs/images/$name.png"
        check "README.md shows docs/images/$name.png" grep -qF "(docs/images/$name.png)" "$SRC/README.md"
    done
fi

# output.radius survives psys check --save.
psys check scene-out.json --save saved.json
expect_rc 0 "check --save with output.radius"
check "saved scene keeps output.radius" grep -q '"radius":[[:space:]]*0.05' saved.json

finish
