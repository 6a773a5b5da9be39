# Plots (docs/cli.md "Plots"): psys run --plot draws kinetic, potential and
# total energy against time; psys plot draws any columns of a psys CSV.
# Needs tests/tools/png_probe ($PSYS_PNG_PROBE, set by tests/render.cmake).
# shellcheck disable=SC2034  # RC is read by the helpers in lib.sh
. "$(dirname "$0")/lib.sh"

PROBE=${PSYS_PNG_PROBE:-}
if [ -z "$PROBE" ] || [ ! -x "$PROBE" ]; then
    echo "plot.sh: set PSYS_PNG_PROBE to the png_probe helper (tests/render.cmake does)" >&2
    exit 2
fi
probe() { "$PROBE" "$@" >probe.txt 2>&1; }
probe_size() { awk '$1 == "size" { print $2 "x" $3 }' probe.txt; }
probe_nonbg() { awk '$1 == "nonbackground" { print $2 }' probe.txt; }
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
dir_listing() { find . -mindepth 1 ! -name out.txt ! -name err.txt ! -name probe.txt | LC_ALL=C sort; }
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

cat >swing.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.001, "duration": 2,
 "particles": [{"id": "p", "x": [0, 0], "fixed": true}, {"id": "b", "x": [1, 0], "mass": 1},
               {"id": "c", "x": [2, 0], "mass": 1}],
 "forces": [{"type": "gravity"}, {"type": "spring", "a": "p", "b": "b", "ks": 1000, "kd": 0.5},
            {"type": "spring", "a": "b", "b": "c", "ks": 1000, "kd": 0.5}]}
EOF

# ---------------------------------------------------------------- psys run --plot

psys run swing.json --plot energy.png --energy energy.csv --every 10
expect_rc 0 "--plot"
expect_stderr_empty "--plot"
expect_png energy.png 800x600 3000 "--plot energy.png (default 800x600)"
psys run swing.json --plot small.png --size 400x300
expect_rc 0 "--plot --size"
expect_png small.png 400x300 1000 "--plot with --size 400x300"
sentinel old.png
psys run swing.json --plot old.png --steps 10
expect_rc 0 "--plot over an existing file"
expect_png old.png 800x600 1000 "--plot over an existing file"
expect_no_tmp "--plot"
sentinel keep.png
cannot_start "--plot with a bad flag" '--fps: only with --render (or output.render)' run swing.json --plot keep.png --fps 3
cannot_start "--plot not PNG" '--plot e.svg: the energy plot is a PNG (got ".svg"; use a name ending in .png)' \
    run swing.json --plot e.svg --out a.csv
cannot_start "--plot into a missing directory" '--plot nodir/e.png: cannot create: No such file or directory' \
    run swing.json --plot nodir/e.png --out a.csv
cannot_start "--plot and --energy to one file" \
    'e.png: the trajectory, energy, checkpoint, render and plot files must be different files' \
    run swing.json --plot e.png --energy e.png
expect_untouched keep.png "--plot runs that could not start"

# ---------------------------------------------------------------- psys plot

psys run swing.json --out traj.csv --every 20
expect_rc 0 "trajectory for psys plot"
psys plot energy.csv --y kinetic,potential,total --out e2.png
expect_rc 0 "psys plot energy columns"
expect_stderr_empty "psys plot energy columns"
expect_stdout_empty "psys plot energy columns"
expect_png e2.png 800x600 3000 "psys plot energy.csv"
psys plot traj.csv --x x --y y --particle 2 --out path.png --size 300x300 --title "second bob"
expect_rc 0 "psys plot a particle's path"
expect_png path.png 300x300 300 "psys plot --x x --y y --particle 2"
psys plot traj.csv --y y --out all.png
expect_rc 0 "psys plot every particle"
expect_png all.png 800x600 1000 "psys plot y of every particle"
psys_in energy.csv plot - --y total --x step --out stdin.png
expect_rc 0 "psys plot from standard input"
expect_png stdin.png 800x600 500 "psys plot - (standard input)"
psys plot energy.csv --y=kinetic --x=t --out=eq.png
expect_rc 0 "psys plot --opt=value"
expect_exists eq.png "psys plot --opt=value"

cannot_start "psys plot unknown column" \
    '--y: no column "speed" in energy.csv (columns: step, t, kinetic, potential, total)' \
    plot energy.csv --y kinetic,speed --out bad.png
cannot_start "psys plot unknown x column" \
    '--x: no column "time" in energy.csv (columns: step, t, kinetic, potential, total)' \
    plot energy.csv --x time --y kinetic --out bad.png
cannot_start "psys plot without --out" \
    'plot: usage: psys plot FILE.csv --y COLUMN[,COLUMN...] [--x COLUMN] --out FILE.png' plot energy.csv --y kinetic
cannot_start "psys plot without --y" \
    'plot: usage: psys plot FILE.csv --y COLUMN[,COLUMN...] [--x COLUMN] --out FILE.png' plot energy.csv --out bad.png
cannot_start "psys plot not PNG" '--out bad.jpg: psys plot writes PNG (use a name ending in .png)' \
    plot energy.csv --y kinetic --out bad.jpg
cannot_start "psys plot missing file" 'nothere.csv: cannot open: No such file or directory' \
    plot nothere.csv --y kinetic --out bad.png
cannot_start "psys plot --particle on an energy file" \
    '--particle: energy.csv has no column "i" (it is not a trajectory)' \
    plot energy.csv --y kinetic --particle 1 --out bad.png
cannot_start "psys plot --particle not there" '--particle: no rows for particle 7 in traj.csv' \
    plot traj.csv --y x --particle 7 --out bad.png
cannot_start "psys plot bad --size" '--size: must be WIDTHxHEIGHT, each from 16 to 8192 (got 0x0)' \
    plot energy.csv --y kinetic --size 0x0 --out bad.png
cannot_start "psys plot unknown option" 'plot: unknown option --bogus (see psys --help)' \
    plot energy.csv --y kinetic --bogus --out bad.png
printf 'a,b\n1,2\n3,x\n' >junk.csv
cannot_start "psys plot a field that is not a number" 'junk.csv: line 3: column "b" is not a number (got "x")' \
    plot junk.csv --y b --out bad.png
printf 'a,b\n1,2\n3\n' >short.csv
cannot_start "psys plot a short row" 'short.csv: line 3: 1 fields, the header has 2' plot short.csv --y b --out bad.png
printf 'a,b\n' >empty.csv
cannot_start "psys plot no rows" 'empty.csv: no rows to plot' plot empty.csv --y b --out bad.png
printf 'step,t,kinetic\n0,0,1\n1,0.5,nan\n2,1,inf\n3,1.5,2\n' >nonfinite.csv
psys plot nonfinite.csv --y kinetic --out nf.png
expect_rc 0 "psys plot skips non-finite values"
expect_png nf.png 800x600 500 "psys plot with nan and inf"
printf 'x,y\n1,5\n2,5\n3,5\n' >flat.csv
psys plot flat.csv --y y --out flat.png
expect_rc 0 "psys plot a constant"
expect_png flat.png 800x600 500 "psys plot a constant column"

psys --help
check "--help mentions psys plot" grep -q 'psys plot FILE.csv' out.txt
for flag in --plot --size --fps --camera --radius; do
    check "--help mentions $flag" grep -q -e "$flag\\b" out.txt
done

finish
