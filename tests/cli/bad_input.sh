# Every class of bad input (docs/scene-format.md, docs/cli.md, docs/semantics.md
# "Failed and interrupted runs"):
#   exit status 2, one message on stderr of the form
#   "psys: FILE: JSON.PATH: what is wrong (got VALUE)", and nothing written:
#   pre-existing --out/--energy/--checkpoint/--save files stay byte-identical
#   and no temporary file (*.psys-tmp-*) is left behind.
. "$(dirname "$0")/lib.sh"

# ---------------------------------------------------------------- helpers

# prepare: pre-existing output files that must survive.
prepare() {
    rm -f ./*.psys-tmp-* out.csv en.csv ck.json saved.json
    sentinel out.csv
    sentinel en.csv
    sentinel ck.json
    sentinel saved.json
}

nothing_written() {
    expect_untouched out.csv "$1 (--out)"
    expect_untouched en.csv "$1 (--energy)"
    expect_untouched ck.json "$1 (--checkpoint)"
    expect_untouched saved.json "$1 (--save)"
    expect_no_tmp "$1"
}

# bad_scene NAME CONTENT MESSAGE: the scene NAME.json holding CONTENT is
# rejected by both `run` and `check` with exactly "psys: NAME.json: MESSAGE".
bad_scene() {
    local name=$1 content=$2 msg=$3
    printf '%s' "$content" >"$name.json"
    prepare
    psys run "$name.json" --steps 3 --out out.csv --energy en.csv --checkpoint ck.json
    expect_rc 2 "run $name"
    expect_stderr "psys: $name.json: $msg" "run $name"
    expect_stdout_empty "run $name"
    nothing_written "run $name"
    psys check "$name.json" --save saved.json
    expect_rc 2 "check $name"
    expect_stderr "psys: $name.json: $msg" "check $name"
    expect_stdout_empty "check $name"
    nothing_written "check $name"
}

# bad_scene_re NAME CONTENT REGEX: as bad_scene, the message matched by an
# extended regular expression (after "psys: NAME.json: ").
bad_scene_re() {
    local name=$1 content=$2 re=$3
    printf '%s' "$content" >"$name.json"
    prepare
    psys run "$name.json" --steps 3 --out out.csv --energy en.csv --checkpoint ck.json
    expect_rc 2 "run $name"
    expect_stderr_re "psys: $name\\.json: $re" "run $name"
    nothing_written "run $name"
    psys check "$name.json" --save saved.json
    expect_rc 2 "check $name"
    expect_stderr_re "psys: $name\\.json: $re" "check $name"
    nothing_written "check $name"
}

# bad_flags LABEL MESSAGE ARGS...: `psys run good.json --out out.csv
# --energy en.csv ARGS...` exits 2 with exactly "psys: MESSAGE".
bad_flags() {
    local label=$1 msg=$2
    shift 2
    prepare
    psys run good.json --out out.csv --energy en.csv "$@"
    expect_rc 2 "flags $label"
    expect_stderr "psys: $msg" "flags $label"
    expect_stdout_empty "flags $label"
    nothing_written "flags $label"
}

# A valid 2-D scene the flag tests start from, and two particles to refer to.
P2='"particles": [{"id": "a", "x": [0, 0]}, {"id": "b", "x": [1, 0]}]'
cat >good.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.01, "steps": 5,
 "particles": [{"id": "a", "x": [0, 0]}, {"id": "b", "x": [1, 0], "v": [0, 1]}],
 "forces": [{"type": "gravity", "g": [0, -9.81]}, {"type": "spring", "a": "a", "b": "b", "ks": 10}]}
EOF

# The good scene really is good (otherwise every check below is meaningless).
prepare
psys run good.json --out out.csv --energy en.csv
expect_rc 0 "good scene runs"
expect_trajectory out.csv 2 2 "good scene output"
prepare

# ---------------------------------------------------------------- empty input

bad_scene empty '' \
    '(root): the scene is empty (a scene is a JSON object starting with "psys": 1)'
bad_scene blank $' \n\t \r\n  \n' \
    '(root): the scene is empty (a scene is a JSON object starting with "psys": 1)'

# ---------------------------------------------------------------- malformed JSON (line and column)

bad_scene missing_comma '{"psys": 1 "dim": 2}' \
    'line 1, column 12: malformed JSON (got ""dim": 2}")'
bad_scene bad_literal $'{"psys": 1,\n  "dim": 2,\n  "dt": tru\n}\n' \
    'line 3, column 9: malformed JSON (got "tru")'
bad_scene array_trailing_comma $'{"psys": 1,\n "particles": [{"x": [0, 0, 0]},]}\n' \
    'line 2, column 33: malformed JSON (got "]}")'
bad_scene trailing_garbage $'{"psys": 1}\n x\n' \
    'line 2, column 2: malformed JSON (got "x")'
# (control characters in messages are shown as "?": a message is one line)
bad_scene control_byte $'{"psys": 1}\n\x01' \
    'line 2, column 1: malformed JSON (got "?")'
# A NUL byte cannot live in a bash string: write the file directly.
printf '{"psys": 1}\0' >nul_byte.json
prepare
psys run nul_byte.json --out out.csv --energy en.csv
expect_rc 2 "run nul_byte"
expect_stderr 'psys: nul_byte.json: (root): the scene contains a NUL byte (not a JSON text file)' "run nul_byte"
nothing_written "run nul_byte"
# The column is where the text stops being JSON: the "}" after a trailing
# comma in an object (cJSON's error pointer is one past it here).
bad_scene object_trailing_comma $'{"psys": 1,}\n' \
    'line 1, column 12: malformed JSON (got "}")'
# A file cut short (no final newline): the problem is the end of the file.
bad_scene truncated $'{"psys": 1,\n  "dim": 2' \
    'line 2, column 11: malformed JSON (got end of file)'

# ---------------------------------------------------------------- root

bad_scene root_array '[1, 2]' '(root): a scene must be a JSON object (got [1,2])'
bad_scene root_string '"psys"' '(root): a scene must be a JSON object (got "psys")'
bad_scene root_number '1' '(root): a scene must be a JSON object (got 1)'
bad_scene no_version '{"dim": 2}' 'psys: required key missing (a scene starts with "psys": 1)'
bad_scene version_2 '{"psys": 2}' 'psys: unsupported format version (this psys reads version 1) (got 2)'
bad_scene version_string '{"psys": "1"}' 'psys: unsupported format version (this psys reads version 1) (got "1")'

# ---------------------------------------------------------------- unknown and duplicate keys

bad_scene unknown_top '{"psys": 1, "dimension": 2}' 'dimension: unknown key'
bad_scene unknown_particle_key '{"psys": 1, "dim": 2, "particles": [{"x": [0, 0]}, {"x": [1, 0], "mas": 2}]}' \
    'particles[1].mas: unknown key'
bad_scene unknown_force_key '{"psys": 1, "dim": 2, "forces": [{"type": "drag", "kd": 1, "kv": 2}]}' \
    'forces[0].kv: unknown key'
bad_scene unknown_spring_key '{"psys": 1, "dim": 2, '"$P2"', "forces": [{"type": "spring", "a": 0, "b": 1, "ks": 1, "length": 2}]}' \
    'forces[0].length: unknown key'
bad_scene unknown_output_key '{"psys": 1, "output": {"every": 2, "traj": "t.csv"}}' \
    'output.traj: unknown key'
bad_scene duplicate_top '{"psys": 1, "dim": 2, "dt": 0.1, "dim": 3}' 'dim: duplicate key'
bad_scene duplicate_nested '{"psys": 1, "dim": 2, "particles": [{"x": [0, 0], "x": [1, 1]}]}' \
    'particles[0].x: duplicate key'

# ---------------------------------------------------------------- dim and vectors

bad_scene dim_4 '{"psys": 1, "dim": 4}' 'dim: must be 2 or 3 (got 4)'
bad_scene dim_1 '{"psys": 1, "dim": 1}' 'dim: must be 2 or 3 (got 1)'
bad_scene dim_fraction '{"psys": 1, "dim": 2.5}' 'dim: must be an integer (got 2.5)'
bad_scene dim_string '{"psys": 1, "dim": "2"}' 'dim: must be an integer (got "2")'
bad_scene vec_long '{"psys": 1, "dim": 2, "particles": [{"x": [0, 0, 0]}]}' \
    'particles[0].x: must be an array of 2 numbers (dim is 2) (got [0,0,0])'
bad_scene vec_short '{"psys": 1, "particles": [{"x": [0, 0]}]}' \
    'particles[0].x: must be an array of 3 numbers (dim is 3) (got [0,0])'
bad_scene vec_scalar '{"psys": 1, "dim": 2, "particles": [{"x": [0, 0], "v": 5}]}' \
    'particles[0].v: must be an array of 2 numbers (dim is 2) (got 5)'
bad_scene vec_gravity '{"psys": 1, "dim": 2, "forces": [{"type": "gravity", "g": [0, 0, -9.81]}]}' \
    'forces[0].g: must be an array of 2 numbers (dim is 2) (got [0,0,-9.81])'
bad_scene vec_string '{"psys": 1, "dim": 2, "particles": [{"x": [0, "a"]}]}' \
    'particles[0].x[1]: must be a finite number (got "a")'
bad_scene vec_null '{"psys": 1, "dim": 2, "particles": [{"x": [null, 0]}]}' \
    'particles[0].x[0]: must be a finite number (got null)'
bad_scene vec_missing '{"psys": 1, "dim": 2, "particles": [{"v": [0, 0]}]}' \
    'particles[0].x: required key missing'

# ---------------------------------------------------------------- numbers out of range
# 1e999 overflows to infinity when parsed: rejected, and the message must
# show the value the user wrote (or inf), not "null".
INF='(1e999|-1e999|inf|-inf|\+inf|Infinity|-Infinity|\+Infinity)'
bad_scene_re inf_vector '{"psys": 1, "dim": 2, "particles": [{"x": [0, 1e999]}]}' \
    "particles\\[0\\]\\.x\\[1\\]: must be a finite number \\(got $INF\\)"
bad_scene_re inf_dt '{"psys": 1, "dt": 1e999}' "dt: must be finite \\(got $INF\\)"
bad_scene_re inf_mass '{"psys": 1, "dim": 2, "particles": [{"x": [0, 0], "mass": 1e999}]}' \
    "particles\\[0\\]\\.mass: must be finite \\(got $INF\\)"
bad_scene_re inf_gravity '{"psys": 1, "dim": 2, "forces": [{"type": "gravity", "g": [0, -1e999]}]}' \
    "forces\\[0\\]\\.g\\[1\\]: must be a finite number \\(got $INF\\)"
# ...while the largest finite numbers, -0 and tiny numbers are accepted.
printf '{"psys": 1, "dim": 2, "dt": 1e-300, "steps": 1, "particles": [{"x": [1.7976931348623157e308, -0.0], "v": [4.9e-324, 0], "mass": 1e308}]}' >big.json
psys check big.json
expect_rc 0 "finite extremes are accepted (stderr: $(cat err.txt))"
bad_scene mass_zero '{"psys": 1, "dim": 2, "particles": [{"x": [0, 0], "mass": 0}]}' \
    'particles[0].mass: must be > 0 (got 0)'
bad_scene mass_negative '{"psys": 1, "dim": 2, "particles": [{"x": [0, 0]}, {"x": [0, 0], "mass": -1.5}]}' \
    'particles[1].mass: must be > 0 (got -1.5)'
bad_scene mass_subnormal '{"psys": 1, "dim": 2, "particles": [{"x": [0, 0], "mass": 1e-320}]}' \
    'particles[0].mass: must be at least 2.2250738585072014e-308 (a normal number, so that 1/mass is finite) (got 9.99988867182683e-321)'
bad_scene mass_string '{"psys": 1, "dim": 2, "particles": [{"x": [0, 0], "mass": "1"}]}' \
    'particles[0].mass: must be a number (got "1")'
bad_scene ks_negative '{"psys": 1, "dim": 2, '"$P2"', "forces": [{"type": "spring", "a": 0, "b": 1, "ks": -1}]}' \
    'forces[0].ks: must be >= 0 (got -1)'
bad_scene kd_negative '{"psys": 1, "dim": 2, '"$P2"', "forces": [{"type": "spring", "a": 0, "b": 1, "ks": 1, "kd": -0.5}]}' \
    'forces[0].kd: must be >= 0 (got -0.5)'
bad_scene rest_negative '{"psys": 1, "dim": 2, '"$P2"', "forces": [{"type": "spring", "a": 0, "b": 1, "ks": 1, "rest": -2}]}' \
    'forces[0].rest: must be >= 0 (got -2)'
bad_scene ks_missing '{"psys": 1, "dim": 2, '"$P2"', "forces": [{"type": "spring", "a": 0, "b": 1}]}' \
    'forces[0].ks: required key missing'
bad_scene drag_negative '{"psys": 1, "dim": 2, "forces": [{"type": "gravity"}, {"type": "drag", "kd": -1}]}' \
    'forces[1].kd: must be >= 0 (got -1)'
bad_scene dt_zero '{"psys": 1, "dt": 0}' 'dt: must be > 0 (got 0)'
bad_scene dt_negative '{"psys": 1, "dt": -0.1}' 'dt: must be > 0 (got -0.1)'
bad_scene duration_negative '{"psys": 1, "duration": -1}' 'duration: must be >= 0 (got -1)'

# ---------------------------------------------------------------- steps / duration

bad_scene steps_and_duration '{"psys": 1, "steps": 10, "duration": 1}' \
    'duration: give either duration or steps, not both (got 1)'
bad_scene steps_fraction '{"psys": 1, "steps": 1.5}' 'steps: must be an integer (got 1.5)'
bad_scene steps_string '{"psys": 1, "steps": "10"}' 'steps: must be an integer (got "10")'
bad_scene steps_negative '{"psys": 1, "steps": -1}' 'steps: must be an integer from 0 to 1e15 (got -1)'
bad_scene every_zero '{"psys": 1, "output": {"every": 0}}' 'output.every: must be an integer from 1 to 1e15 (got 0)'

# ---------------------------------------------------------------- particle references

bad_scene ref_unknown_id '{"psys": 1, "dim": 2, '"$P2"', "forces": [{"type": "spring", "a": "a", "b": "c", "ks": 1}]}' \
    'forces[0].b: unknown particle id (got "c")'
bad_scene ref_index_range '{"psys": 1, "dim": 2, '"$P2"', "forces": [{"type": "spring", "a": 2, "b": 0, "ks": 1}]}' \
    'forces[0].a: particle index out of range (particles are numbered 0 to 1) (got 2)'
bad_scene ref_index_negative '{"psys": 1, "dim": 2, '"$P2"', "forces": [{"type": "spring", "a": 0, "b": -1, "ks": 1}]}' \
    'forces[0].b: particle index out of range (particles are numbered 0 to 1) (got -1)'
bad_scene ref_bool '{"psys": 1, "dim": 2, '"$P2"', "forces": [{"type": "spring", "a": 0, "b": true, "ks": 1}]}' \
    'forces[0].b: must be a particle id (string) or index (integer) (got true)'
bad_scene duplicate_id '{"psys": 1, "dim": 2, "particles": [{"id": "a", "x": [0, 0]}, {"id": "b", "x": [1, 0]}, {"id": "a", "x": [2, 0]}]}' \
    'particles[2].id: duplicate particle id (got "a")'
bad_scene empty_id '{"psys": 1, "dim": 2, "particles": [{"id": "", "x": [0, 0]}]}' \
    'particles[0].id: must be a non-empty string (got "")'
bad_scene spring_to_itself '{"psys": 1, "dim": 2, '"$P2"', "forces": [{"type": "spring", "a": "b", "b": 1, "ks": 1}]}' \
    'forces[0].b: a spring needs two different particles (got 1)'

# ---------------------------------------------------------------- names

# Unknown names: the message lists the known names, and that list is true:
# every name this psys accepts is in it (checked by trying each documented
# name with a minimal valid example), so the list cannot go stale when
# integrators or force types are added.
bad_scene_re unknown_integrator '{"psys": 1, "integrator": "rk5"}' \
    'integrator: unknown integrator \(known: [a-z0-9, -]+\) \(got "rk5"\)'
integrators_known=$(sed -n 's/.*unknown integrator (known: \([^)]*\)).*/\1/p' err.txt)
for integ in euler midpoint rk4 symplectic-euler verlet rk45 implicit-euler; do
    printf '{"psys": 1, "integrator": "%s", "steps": 1, "particles": [{"x": [0, 0, 0]}]}' "$integ" >integ.json
    psys check integ.json
    if [ "$RC" -eq 0 ]; then
        check "integrator $integ is accepted, so the unknown-integrator message lists it (list: $integrators_known)" \
            grep -qw -e "$integ" <<<"${integrators_known//, /$'\n'}"
    elif [ "$integ" != implicit-euler ]; then
        fail "integrator $integ (docs/scene-format.md "Top-level keys") is rejected: $(cat err.txt)"
    fi
done
bad_scene_re unknown_force_type '{"psys": 1, "forces": [{"type": "magnet"}]}' \
    'forces\[0\]\.type: unknown force type \(known: [a-z, -]+\) \(got "magnet"\)'
forces_known=$(sed -n 's/.*unknown force type (known: \([^)]*\)).*/\1/p' err.txt)
for example in \
    'gravity|{"type": "gravity", "g": [0, -1]}' \
    'drag|{"type": "drag", "kd": 1}' \
    'spring|{"type": "spring", "a": 0, "b": 1, "ks": 1}' \
    'behavior|{"type": "behavior", "function": "distance", "particles": [0, 1], "r": 1, "ks": 1, "kd": 0}' \
    'pair|{"type": "pair", "law": "gravity", "G": 1, "softening": 0.1}' \
    'mouse-spring|{"type": "mouse-spring", "particle": 0, "ks": 1, "kd": 0, "target": [0, 0]}'; do
    type=${example%%|*}
    printf '{"psys": 1, "dim": 2, %s, "forces": [%s]}' "$P2" "${example#*|}" >forcetype.json
    psys check forcetype.json
    if [ "$RC" -eq 0 ]; then
        check "force type $type is accepted, so the unknown-force-type message lists it (list: $forces_known)" \
            grep -qx -e "$type" <<<"${forces_known//, /$'\n'}"
    fi
done
bad_scene force_without_type '{"psys": 1, "forces": [{"kd": 1}]}' 'forces[0].type: required key missing'
bad_scene particles_not_array '{"psys": 1, "particles": {"x": [0, 0, 0]}}' \
    'particles: must be an array (got {"x":[0,0,0]})'
bad_scene particle_not_object '{"psys": 1, "particles": [[0, 0, 0]]}' \
    'particles[0]: a particle must be an object (got [0,0,0])'
bad_scene fixed_not_bool '{"psys": 1, "particles": [{"x": [0, 0, 0], "fixed": 1}]}' \
    'particles[0].fixed: must be true or false (got 1)'

# ---------------------------------------------------------------- planes and controls (docs/scene-format.md, docs/semantics.md)

bad_scene plane_zero_normal '{"psys": 1, "dim": 2, "planes": [{"point": [0, 0], "normal": [0, 0]}]}' \
    'planes[0].normal: must not be zero (got [0,0])'
bad_scene plane_restitution '{"psys": 1, "dim": 2, "planes": [{"point": [0, 0], "normal": [0, 1], "restitution": 1.5}]}' \
    'planes[0].restitution: must be from 0 to 1 (got 1.5)'
bad_scene plane_friction '{"psys": 1, "dim": 2, "planes": [{"point": [0, 0], "normal": [0, 1], "friction": -1}]}' \
    'planes[0].friction: must be >= 0 (got -1)'
bad_scene plane_response '{"psys": 1, "dim": 2, "planes": [{"point": [0, 0], "normal": [0, 1], "response": "bounce"}]}' \
    'planes[0].response: must be "rollback" or "displace" (got "bounce")'
bad_scene control_type '{"psys": 1, "dim": 2, "particles": [{"x": [0, 0], "control": {"type": "spin"}}]}' \
    'particles[0].control.type: unknown control type (known: circle, oscillate, keyframes) (got "spin")'

# ---------------------------------------------------------------- scene from standard input

printf '{"psys": 1, "dim": 5}' >stdin.json
prepare
psys_in stdin.json run - --out out.csv --energy en.csv
expect_rc 2 "run - (bad scene on stdin)"
expect_stderr 'psys: <stdin>: dim: must be 2 or 3 (got 5)' "run - (bad scene on stdin)"
nothing_written "run - (bad scene on stdin)"

# ---------------------------------------------------------------- scene file that does not exist

prepare
psys run missing.json --out out.csv --energy en.csv --checkpoint ck.json
expect_rc 2 "run missing.json"
expect_stderr 'psys: missing.json: cannot open: No such file or directory' "run missing.json"
nothing_written "run missing.json"
psys check missing.json --save saved.json
expect_rc 2 "check missing.json"
expect_stderr 'psys: missing.json: cannot open: No such file or directory' "check missing.json"
nothing_written "check missing.json"
prepare
psys run good.json --resume missing-ck.json --out out.csv
expect_rc 2 "run --resume missing-ck.json"
expect_stderr 'psys: missing-ck.json: cannot open: No such file or directory' "run --resume missing-ck.json"
nothing_written "run --resume missing-ck.json"
# A scene is not a checkpoint.
prepare
psys run good.json --resume good.json --out out.csv
expect_rc 2 "run --resume SCENE"
expect_stderr 'psys: good.json: checkpoint: required key missing (not a checkpoint written by --checkpoint)' \
    "run --resume SCENE"
nothing_written "run --resume SCENE"

# ---------------------------------------------------------------- bad flags

bad_flags 'dt abc' '--dt: must be a finite number > 0 (got abc)' --dt abc
bad_flags 'dt 0' '--dt: must be a finite number > 0 (got 0)' --dt 0
bad_flags 'dt -1' '--dt: must be a finite number > 0 (got -1)' --dt -1
bad_flags 'dt inf' '--dt: must be a finite number > 0 (got inf)' --dt inf
bad_flags 'dt nan' '--dt: must be a finite number > 0 (got nan)' --dt nan
bad_flags 'dt=' '--dt: must be a finite number > 0 (got )' --dt=
bad_flags 'steps -1' '--steps: must be an integer >= 0 (got -1)' --steps -1
bad_flags 'steps 1.5' '--steps: must be an integer >= 0 (got 1.5)' --steps 1.5
bad_flags 'steps ten' '--steps: must be an integer >= 0 (got ten)' --steps ten
bad_flags 'duration -1' '--duration: must be a finite number >= 0 (got -1)' --duration -1
bad_flags 'every 0' '--every: must be an integer >= 1 (got 0)' --every 0
bad_flags 'threads 0' '--threads: must be an integer from 1 to 4096 (got 0)' --threads 0
prepare
psys run good.json --out out.csv --energy en.csv --integrator nope
expect_rc 2 "flags integrator nope"
expect_stderr_re 'psys: --integrator: unknown integrator \(got nope; known: [a-z0-9, -]+\)' "flags integrator nope"
expect_eq "$integrators_known" "$(sed -n 's/.*; known: \([^)]*\)).*/\1/p' err.txt)" \
    "--integrator nope lists the same integrators as the scene message"
nothing_written "flags integrator nope"
bad_flags 'unknown option' 'run: unknown option --bogus (see psys --help)' --bogus
bad_flags 'unknown short option' 'run: unknown option -x (see psys --help)' -x
bad_flags 'steps and duration' 'run: give either --steps or --duration, not both' --steps 3 --duration 1
bad_flags 'duration and steps' 'run: give either --steps or --duration, not both' --duration 1 --steps 3
bad_flags 'missing value' '--dt needs a value (see psys --help)' --dt
bad_flags 'missing value (steps)' '--steps needs a value (see psys --help)' --steps
bad_flags 'two scenes' 'run: more than one scene given (good.json and other.json)' other.json
bad_flags 'unknown format' '--out x.txt: unknown trajectory format (got ".txt"; use .csv, .vtp, .vtk or .xyz)' --out x.txt

# One file under two names is one file: outputs are compared as files, not
# as strings; and no output may replace the scene or checkpoint read (a
# checkpoint may: --resume ck --checkpoint ck goes on in place).
bad_flags 'one file, two spellings' \
    'out.csv: the trajectory, energy, checkpoint, render and plot files must be different files' --energy ./out.csv
bad_flags 'one file, through its directory' \
    'out.csv: the trajectory, energy, checkpoint, render and plot files must be different files' --energy "$PWD/out.csv"
prepare
ln -f en.csv hard.csv
psys run good.json --out out.csv --energy en.csv --checkpoint hard.csv
expect_rc 2 "one file under two hard links"
expect_stderr 'psys: en.csv: the trajectory, energy, checkpoint, render and plot files must be different files' \
    "one file under two hard links"
nothing_written "one file under two hard links"
ln -sf out.csv soft.csv
psys run good.json --out out.csv --energy soft.csv
expect_rc 2 "a file and a link to it"
nothing_written "a file and a link to it"
rm -f hard.csv soft.csv
cp good.json good.json.orig
bad_flags 'the energy file names the scene' 'good.json: the energy file would replace the scene it reads' --energy good.json
expect_untouched good.json "the energy file names the scene"
psys run good.json --steps 2 --checkpoint inplace.json
psys run --resume inplace.json --steps 2 --checkpoint inplace.json
expect_rc 0 "--resume and --checkpoint of one file go on in place"
check "the checkpoint went on in place (step 4)" grep -q '"step":[[:space:]]*4' inplace.json
psys run good.json --energy /dev/null --checkpoint /dev/null
expect_rc 0 "/dev/null twice is allowed"

# Bad flags must fail before the scene is even looked at... or after: either
# way a bad scene plus a good flag still writes nothing (covered above), and
# a good scene plus a bad flag writes nothing (covered here).

# ---------------------------------------------------------------- commands, --help, --version

psys
expect_rc 2 "psys with no arguments"
expect_stdout_empty "psys with no arguments"
check "psys with no arguments prints the usage on stderr" grep -q 'psys run SCENE' err.txt

psys frobnicate
expect_rc 2 "unknown command"
expect_stderr 'psys: unknown command "frobnicate" (see psys --help)' "unknown command"

psys run
expect_rc 2 "run without a scene"
expect_stderr 'psys: run: no scene given (usage: psys run SCENE [options]; see psys --help)' "run without a scene"

psys check
expect_rc 2 "check without a scene"
expect_stderr 'psys: check: no scene given (usage: psys check SCENE [--save FILE])' "check without a scene"

prepare
psys check good.json --bogus
expect_rc 2 "check --bogus"
expect_stderr 'psys: check: unknown option --bogus (see psys --help)' "check --bogus"
nothing_written "check --bogus"

psys check good.json --save
expect_rc 2 "check --save without a value"
expect_stderr 'psys: --save needs a value (see psys --help)' "check --save without a value"

# psys bench cloth-N: any N in 2..4096 runs that sheet; other names are unknown cases
psys bench cloth-8 --steps 1 --reps 1 --bandwidth 1
expect_rc 0 "bench cloth-8"
check "bench cloth-8 runs the 8x8 sheet" \
    grep -q '"case":"cloth-8","integrator":"rk4","n":64,"particles":64,"springs":306,"planes":0,' out.txt
# rows of 8: springs 1, 2, 7, 8, 9 and 16 apart, 2152 in all over 306 springs
check "bench cloth-8 numbers the sheet by rows" grep -q '"mean_spring_index_gap":7.0}$' out.txt
psys bench cloth-8-shuffled --steps 1 --reps 1 --bandwidth 1
expect_rc 0 "bench cloth-8-shuffled"
check "bench cloth-8-shuffled runs the 8x8 sheet" \
    grep -q '"case":"cloth-8-shuffled","integrator":"rk4","n":64,"particles":64,"springs":306,' out.txt
# the fixed shuffle scatters the same springs' ends (random pairs of 64: about 21 apart)
check "bench cloth-8-shuffled numbers the sheet at random" grep -q '"mean_spring_index_gap":20.6}$' out.txt
# cloth-N-floor: the same sheet lying on a floor through it (every particle in contact)
psys bench cloth-8-floor --steps 1 --reps 1 --bandwidth 1
expect_rc 0 "bench cloth-8-floor"
check "bench cloth-8-floor runs the 8x8 sheet" \
    grep -q '"case":"cloth-8-floor","integrator":"rk4","n":64,"particles":64,"springs":306,"planes":1,' out.txt
for name in cloth-1 cloth-4097 cloth-8x cloth- cloth--8 cloth-8-shuffledx cloth-shuffled cloth-1-shuffled \
    cloth-8-floorx cloth-floor cloth-1-floor cloth-8-floor-shuffled; do
    psys bench "$name" --steps 1 --reps 1 --bandwidth 1
    expect_rc 2 "bench $name"
    expect_stderr "psys: bench: unknown case \"$name\" (cases: cloth-100, cloth-256, cloth-1024, rope-1000000, lj-melt, nbody-4096; cloth-N, cloth-N-shuffled and cloth-N-floor for N in 2..4096)" "bench $name"
    expect_stdout_empty "bench $name"
done

psys --help
expect_rc 0 "--help"
expect_stderr_empty "--help"
for flag in --dt --steps --duration --integrator --every --out --energy --render --threads \
    --checkpoint --resume --quiet --save --version; do
    check "--help mentions $flag" grep -q -e "$flag\\b" out.txt
done
for cmd in 'psys run SCENE' 'psys check SCENE' 'psys view' 'psys bench'; do
    check "--help mentions \"$cmd\"" grep -qF "$cmd" out.txt
done
for integ in euler midpoint rk4 symplectic-euler verlet rk45; do
    check "--help names the integrator $integ" grep -qw -e "$integ" out.txt
done
cp out.txt help.txt
for cmd in run check bench plot import; do
    for h in --help -h; do
        psys "$cmd" "$h"
        expect_rc 0 "$cmd $h"
        check "$cmd $h prints psys --help" cmp -s out.txt help.txt
    done
done
psys frobnicate --help
expect_rc 2 "frobnicate --help"
psys --version extra
expect_rc 2 "--version extra"
expect_stderr 'psys: --version takes no arguments (got extra)' "--version extra"
bad_flags 'hexadecimal dt' '--dt: must be a finite number > 0 (got 0x10)' --dt 0x10

psys --version
expect_rc 0 "--version"
expect_stderr_empty "--version"
check "--version prints \"psys X.Y.Z\" (got: $(cat out.txt))" grep -Eqx 'psys [0-9]+\.[0-9]+\.[0-9]+' out.txt
if [ -n "$SRC" ] && [ -f "$SRC/include/psys/psys.h" ]; then
    v=$(sed -n 's/^#define PSYS_VERSION_STRING "\(.*\)"$/\1/p' "$SRC/include/psys/psys.h")
    expect_eq "psys $v" "$(cat out.txt)" "--version matches PSYS_VERSION_STRING"
fi

expect_no_tmp "whole test"
finish
