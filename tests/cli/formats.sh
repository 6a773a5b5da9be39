# Trajectory formats (docs/cli.md "Trajectory formats"), each parsed back:
#   --out traj.vtp   one VTK XML PolyData file per frame (well-formed XML,
#                    NumberOfPoints = particles, every array complete) and
#                    traj.pvd listing every frame with its time;
#   --out traj.vtk   the same frames in the legacy format;
#   --out traj.xyz   extended XYZ: one frame per output frame, Properties=
#                    with 10 columns, Time= matching the CSV.
# Frames are those of the CSV (--every, the last step always), with the
# same %.17g numbers.
# shellcheck disable=SC2034  # RC is read by the helpers in lib.sh
. "$(dirname "$0")/lib.sh"

if ! command -v xmllint >/dev/null 2>&1; then
    echo "formats.sh: xmllint is not installed (Debian libxml2-utils; scripts/install-deps.sh installs it)" >&2
    exit 1
fi

cat >scene.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.01, "steps": 25,
 "particles": [{"id": "p", "x": [0, 0], "fixed": true},
               {"id": "b", "x": [1, 0], "v": [0, 0.5], "mass": 0.5},
               {"x": [1, 1], "mass": 2},
               {"id": "m", "x": [-1, 0], "control": {"type": "oscillate", "center": [-1, 0], "direction": [0, 1],
                                                     "amplitude": 0.1, "omega": 3}}],
 "forces": [{"type": "gravity", "g": [0, -9.81]},
            {"type": "spring", "a": "p", "b": "b", "ks": 100, "kd": 0.5},
            {"type": "spring", "a": 1, "b": 2, "ks": 50, "rest": 0.8},
            {"type": "spring", "a": "m", "b": "p", "ks": 10}]}
EOF
cat >scene3.json <<'EOF'
{"psys": 1, "dim": 3, "dt": 0.01, "steps": 10,
 "structures": [{"type": "cloth", "id": "c", "origin": [0, 0, 0], "size": [4, 3], "spacing": 0.1,
                 "mass": 0.01, "ks": 100, "pin": [[0, 0]]}],
 "forces": [{"type": "gravity"}]}
EOF

psys run scene.json --out ref.csv --every 10
expect_rc 0 "reference CSV"
expect_eq "0 10 20 25" "$(csv_steps_line ref.csv)" "reference frames"

# ---------------------------------------------------------------- VTP + PVD

psys run scene.json --out traj.vtp --every 10
expect_rc 0 "--out traj.vtp"
expect_stderr_empty "--out traj.vtp"
expect_eq "traj.pvd traj_000000.vtp traj_000001.vtp traj_000002.vtp traj_000003.vtp" \
    "$(ls traj* | tr '\n' ' ' | sed 's/ $//')" "VTP: one file per frame and the .pvd"
expect_no_tmp "VTP"
for f in traj.pvd traj_*.vtp; do
    check "$f is well-formed XML ($(xmllint --noout "$f" 2>&1 | head -n 2))" xmllint --noout "$f"
done
# vtp_value FILE XPATH: a value by XPath.
vtp_value() { xmllint --xpath "$2" "$1" 2>/dev/null; }
# vtp_words FILE XPATH: the number of numbers in an element's text.
vtp_words() { xmllint --xpath "string($2)" "$1" 2>/dev/null | wc -w | tr -d ' '; }
for k in 0 1 2 3; do
    f=traj_00000$k.vtp
    expect_eq "PolyData" "$(vtp_value "$f" 'string(/VTKFile/@type)')" "$f: VTKFile type"
    expect_eq 4 "$(vtp_value "$f" 'string(//Piece/@NumberOfPoints)')" "$f: NumberOfPoints"
    expect_eq 4 "$(vtp_value "$f" 'string(//Piece/@NumberOfVerts)')" "$f: NumberOfVerts"
    expect_eq 3 "$(vtp_value "$f" 'string(//Piece/@NumberOfLines)')" "$f: NumberOfLines (springs)"
    expect_eq 12 "$(vtp_words "$f" '//Points/DataArray')" "$f: 4 points × 3 coordinates"
    expect_eq 12 "$(vtp_words "$f" '//PointData/DataArray[@Name="velocity"]')" "$f: velocity array"
    expect_eq 4 "$(vtp_words "$f" '//PointData/DataArray[@Name="mass"]')" "$f: mass array"
    expect_eq 4 "$(vtp_words "$f" '//PointData/DataArray[@Name="flags"]')" "$f: flags array"
    expect_eq 6 "$(vtp_words "$f" '//Lines/DataArray[@Name="connectivity"]')" "$f: line connectivity"
    expect_eq "2 4 6" "$(vtp_value "$f" 'string(//Lines/DataArray[@Name="offsets"])' | tr -s ' \n' ' ' | sed 's/^ //; s/ $//')" \
        "$f: line offsets"
done
expect_eq "0 1 1 2 3 0" \
    "$(vtp_value traj_000000.vtp 'string(//Lines/DataArray[@Name="connectivity"])' | tr -s ' \n' ' ' | sed 's/^ //; s/ $//')" \
    "VTP: springs as lines (0-1, 1-2, 3-0)"
expect_eq "1 0 0 2" "$(vtp_value traj_000000.vtp 'string(//PointData/DataArray[@Name="flags"])' | tr -s ' \n' ' ' | sed 's/^ //; s/ $//')" \
    "VTP: flags mark the fixed and the controlled particle"
expect_eq "1 0.5 2 1" "$(vtp_value traj_000001.vtp 'string(//PointData/DataArray[@Name="mass"])' | tr -s ' \n' ' ' | sed 's/^ //; s/ $//')" \
    "VTP: masses"
# Positions and times are the CSV's, digit for digit (z = 0 in 2-D).
for k in 0 1 2 3; do
    step=$(csv_steps ref.csv | sed -n "$((k + 1))p")
    want=$(awk -F, -v s="$step" 'NR > 1 && $1 == s { printf "%s %s 0 ", $4, $5 }' ref.csv | sed 's/ $//')
    got=$(vtp_value traj_00000$k.vtp 'string(//Points/DataArray)' | tr -s ' \n' ' ' | sed 's/^ //; s/ $//')
    expect_eq "$want" "$got" "VTP frame $k: points equal the CSV rows of step $step"
    t=$(awk -F, -v s="$step" 'NR > 1 && $1 == s { print $2; exit }' ref.csv)
    expect_eq "$t" "$(vtp_value traj_00000$k.vtp 'string(//FieldData/DataArray[@Name="TimeValue"])')" "VTP frame $k: TimeValue"
    expect_eq "$step" "$(vtp_value traj_00000$k.vtp 'string(//FieldData/DataArray[@Name="step"])')" "VTP frame $k: step"
done
# The series lists every frame, in order, with its time.
expect_eq "Collection" "$(vtp_value traj.pvd 'string(/VTKFile/@type)')" "PVD: VTKFile type"
expect_eq 4 "$(vtp_value traj.pvd 'count(//DataSet)')" "PVD lists every frame"
for k in 1 2 3 4; do
    expect_eq "traj_00000$((k - 1)).vtp" "$(vtp_value traj.pvd "string(//DataSet[$k]/@file)")" "PVD entry $k: file"
    step=$(csv_steps ref.csv | sed -n "${k}p")
    t=$(awk -F, -v s="$step" 'NR > 1 && $1 == s { print $2; exit }' ref.csv)
    expect_eq "$t" "$(vtp_value traj.pvd "string(//DataSet[$k]/@timestep)")" "PVD entry $k: timestep"
done
# 3-D: springs of a cloth, 12 points.
mkdir sub
psys run scene3.json --out sub/cloth.vtp --every 5
expect_rc 0 "3-D VTP in a subdirectory"
expect_eq "cloth.pvd cloth_000000.vtp cloth_000001.vtp cloth_000002.vtp" "$(ls sub | tr '\n' ' ' | sed 's/ $//')" \
    "3-D VTP files"
check "3-D VTP well-formed" xmllint --noout sub/cloth.pvd sub/cloth_000000.vtp sub/cloth_000001.vtp sub/cloth_000002.vtp
expect_eq 12 "$(vtp_value sub/cloth_000002.vtp 'string(//Piece/@NumberOfPoints)')" "3-D VTP NumberOfPoints"
expect_eq 36 "$(vtp_words sub/cloth_000002.vtp '//Points/DataArray')" "3-D VTP points"
expect_eq "cloth_000002.vtp" "$(vtp_value sub/cloth.pvd 'string(//DataSet[3]/@file)')" \
    "PVD names frames relative to itself"

# ---------------------------------------------------------------- legacy VTK

psys run scene.json --out legacy.vtk --every 10
expect_rc 0 "--out legacy.vtk"
expect_eq "legacy.pvd legacy_000000.vtk legacy_000001.vtk legacy_000002.vtk legacy_000003.vtk" \
    "$(ls legacy* | tr '\n' ' ' | sed 's/ $//')" "VTK: one file per frame and the .pvd"
check "legacy .pvd well-formed" xmllint --noout legacy.pvd
expect_eq "# vtk DataFile Version 3.0" "$(head -n 1 legacy_000002.vtk)" "VTK header"
expect_eq "DATASET POLYDATA" "$(sed -n 4p legacy_000002.vtk)" "VTK dataset"
check "VTK POINTS 4 double" grep -qx 'POINTS 4 double' legacy_000002.vtk
check "VTK LINES 3 9" grep -qx 'LINES 3 9' legacy_000002.vtk
check "VTK POINT_DATA 4" grep -qx 'POINT_DATA 4' legacy_000002.vtk
expect_eq "$(awk '/^POINTS/ { n = 4; next } n > 0 { print; n-- }' legacy_000003.vtk | tr '\n' ' ' | sed 's/ $//')" \
    "$(awk -F, 'NR > 1 && $1 == 25 { printf "%s %s 0 ", $4, $5 }' ref.csv | sed 's/ $//')" "VTK points equal the CSV"

# ---------------------------------------------------------------- extended XYZ

psys run scene.json --out traj.xyz --every 10
expect_rc 0 "--out traj.xyz"
expect_stderr_empty "--out traj.xyz"
expect_no_tmp "XYZ"
# xyz_check FILE N: whole frames of N particles, each with a Properties=
# comment whose columns add up to the fields of every row, Time= and step=.
xyz_summary() {
    awk -v want="$2" '
        function fail(msg) { printf "line %d: %s\n", NR, msg; bad = 1; exit 1 }
        state == 0 { if ($0 != want) fail("particle count \"" $0 "\", expected " want); n = $0; state = 1; next }
        state == 1 {
            if (!match($0, /Properties=[^ ]+/)) fail("no Properties=")
            props = substr($0, RSTART + 11, RLENGTH - 11)
            k = split(props, p, ":"); cols = 0; names = ""
            for (j = 1; j + 2 <= k; j += 3) { cols += p[j + 2]; names = names p[j] "/" p[j + 1] p[j + 2] " " }
            if (!match($0, /Time=[^ ]+/)) fail("no Time=")
            t = substr($0, RSTART + 5, RLENGTH - 5)
            if (!match($0, /step=[^ ]+/)) fail("no step=")
            s = substr($0, RSTART + 5, RLENGTH - 5)
            frames++; times = times t " "; steps = steps s " "; left = n; state = 2; next
        }
        state == 2 {
            if (NF != cols) fail(NF " fields, Properties= says " cols)
            if (--left == 0) state = 0
        }
        END {
            if (bad) exit 1
            if (state != 0) { print "incomplete last frame"; exit 1 }
            printf "frames %d\ncolumns %d\nnames %s\nsteps %s\ntimes %s\n", frames, cols, names, steps, times
        }' "$1"
}
if summary=$(xyz_summary traj.xyz 4); then ok; else fail "XYZ is not whole frames: $summary"; fi
expect_eq "frames 4" "$(sed -n 1p <<<"$summary")" "XYZ frame count"
expect_eq "columns 10" "$(sed -n 2p <<<"$summary")" "XYZ columns"
expect_eq "names species/S1 pos/R3 velo/R3 mass/R1 id/I1 flags/I1 " "$(sed -n 3p <<<"$summary")" "XYZ Properties="
expect_eq "steps $(csv_steps_line ref.csv) " "$(sed -n 4p <<<"$summary")" "XYZ step= follows the CSV frames"
expect_eq "times $(awk -F, 'NR > 1 && $3 == 0 { printf "%s ", $2 }' ref.csv)" "$(sed -n 5p <<<"$summary")" \
    "XYZ Time= equals the CSV's t"
check "XYZ says pbc=\"F F F\"" grep -q 'pbc="F F F"' traj.xyz
# Rows equal the CSV: x y 0 vx vy 0, masses, ids, flags.
want=$(awk -F, 'NR > 1 { printf "X %s %s 0 %s %s 0\n", $4, $5, $6, $7 }' ref.csv)
got=$(awk 'NF == 10 { print $1, $2, $3, $4, $5, $6, $7 }' traj.xyz)
expect_eq "$want" "$got" "XYZ rows equal the CSV rows"
expect_eq "0.5 1 0" "$(awk 'NF == 10 && $9 == 1 { print $8, $9, $10; exit }' traj.xyz)" "XYZ mass, id, flags of particle 1"
expect_eq "2" "$(awk 'NF == 10 && $9 == 3 { print $10; exit }' traj.xyz)" "XYZ flags of the controlled particle"
# 3-D: the z column is the scene's.
psys run scene3.json --out c3.xyz --every 5
expect_rc 0 "3-D XYZ"
if summary=$(xyz_summary c3.xyz 12); then ok; else fail "3-D XYZ: $summary"; fi
expect_eq "frames 3" "$(sed -n 1p <<<"$summary")" "3-D XYZ frame count"
expect_eq "X 0.30000000000000004 0.20000000000000001 0" "$(awk 'NF == 10 && $9 == 11 { print $1, $2, $3, $4; exit }' c3.xyz)" \
    "3-D XYZ positions"

# ---------------------------------------------------------------- real readers, where installed

# VTK's own readers (Debian python3-vtk9) and ASE (python3-ase), when a
# Python with them is installed; skipped otherwise.
for py in python3 /usr/bin/python3; do
    if command -v "$py" >/dev/null 2>&1 && "$py" -c 'import vtk' >/dev/null 2>&1; then
        got=$("$py" - <<'PY' 2>&1
import vtk
r = vtk.vtkXMLPolyDataReader(); r.SetFileName("traj_000003.vtp"); r.Update(); p = r.GetOutput()
l = vtk.vtkPolyDataReader(); l.SetFileName("legacy_000003.vtk"); l.Update(); q = l.GetOutput()
print(p.GetNumberOfPoints(), p.GetNumberOfLines(), p.GetPointData().GetArray("velocity").GetNumberOfComponents(),
      p.GetFieldData().GetArray("TimeValue").GetValue(0), q.GetNumberOfPoints(), q.GetNumberOfLines(),
      q.GetPointData().GetArray("flags").GetValue(0), all(p.GetPoint(i) == q.GetPoint(i) for i in range(4)))
PY
)
        expect_eq "4 3 3 0.25 4 3 1 True" "$got" "VTK's readers read the .vtp and .vtk frames"
        break
    fi
done
for py in python3 /usr/bin/python3; do
    if command -v "$py" >/dev/null 2>&1 && "$py" -c 'import ase.io' >/dev/null 2>&1; then
        got=$("$py" - <<'PY' 2>&1
import ase.io
f = ase.io.read("traj.xyz", index=":")
print(len(f), len(f[0]), f[-1].info["Time"], f[-1].info["step"], " ".join("%.17g" % c for c in f[1].positions[1]),
      " ".join("%g" % m for m in f[0].arrays["mass"]))
PY
)
        want="4 4 0.25 25 $(awk -F, 'NR > 1 && $1 == 10 && $3 == 1 { printf "%s %s 0", $4, $5 }' ref.csv) 1 0.5 2 1"
        expect_eq "$want" "$got" "ASE reads the extended XYZ"
        break
    fi
done

# ---------------------------------------------------------------- frames, failures, bad paths

# A run that fails midway keeps every frame up to the last good state.
psys run scene.json --out blow.xyz --dt 5 --integrator euler --steps 400 --every 1
expect_rc 1 "failing run with --out .xyz"
if summary=$(xyz_summary blow.xyz 4); then ok; else fail "failed run XYZ: $summary"; fi
psys run scene.json --out blow.vtp --dt 5 --integrator euler --steps 400 --every 1
expect_rc 1 "failing run with --out .vtp"
check "failed run: .pvd well-formed" xmllint --noout blow.pvd
expect_eq "$(ls blow_*.vtp | wc -l | tr -d ' ')" "$(vtp_value blow.pvd 'count(//DataSet)')" \
    "failed run: .pvd lists every frame written"

dir_listing() { find . -mindepth 1 ! -name out.txt ! -name err.txt | LC_ALL=C sort; }
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
cannot_start "unknown trajectory format" \
    '--out t.txt: unknown trajectory format (got ".txt"; use .csv, .vtp, .vtk or .xyz)' run scene.json --out t.txt
cannot_start "VTP into a missing directory" '--out nodir/t.pvd: cannot create: No such file or directory' \
    run scene.json --out nodir/t.vtp
cannot_start "XYZ into a missing directory" '--out nodir/t.xyz: cannot create: No such file or directory' \
    run scene.json --out nodir/t.xyz
cannot_start "VTP series and checkpoint to one file" \
    't.pvd: the trajectory, energy, checkpoint, render and plot files must be different files' \
    run scene.json --out t.vtp --checkpoint t.pvd
sed 's/"steps": 25,/"steps": 25, "output": {"trajectory": "scene.xyz"},/' scene.json >with-xyz.json
psys run with-xyz.json
expect_rc 0 "output.trajectory .xyz"
expect_exists scene.xyz "output.trajectory .xyz"

finish
