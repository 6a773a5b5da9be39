# implicit-euler from the command line: a stiff hanging cloth that rk4 cannot
# run at dt = 1/60 (exit 1, the message names the step and a particle) runs
# with implicit-euler; the warning when conjugate gradient stops short (and
# --quiet silencing it); the scene keys cg_tolerance and cg_max_iterations:
# validation messages, saving (only when not default) and exact round trips.
. "$(dirname "$0")/lib.sh"

# The 20×20 cloth: ks 1e5, kd 10, mass 0.01, spacing 0.05, flat in the x–z
# plane, pinned at two corners, under gravity (it falls and swings).
cloth_scene() { # NAME INTEGRATOR N EXTRA-TOP-LEVEL-KEYS
    cat >"$1" <<EOF
{"psys": 1, "dim": 3, "integrator": "$2", "dt": 0.016666666666666666, "duration": 10, $4
 "structures": [{"type": "cloth", "id": "sheet", "origin": [0, 0, 0], "size": [$3, $3], "spacing": 0.05,
   "axes": [[1, 0, 0], [0, 0, 1]], "mass": 0.01, "ks": 1e5, "kd": 10, "pin": [[0, 0], [$(($3 - 1)), 0]]}],
 "forces": [{"type": "gravity"}]}
EOF
}

# ---- rk4 blows up on the stiff cloth, cleanly ----
cloth_scene cloth.json rk4 20 ""
sentinel out.csv
psys run cloth.json --out out.csv --every 1 --quiet # --quiet: no dt stability warning (guardrails.sh)
expect_rc 1 "rk4 cloth: exit status"
expect_stdout_empty "rk4 cloth"
expect_trajectory out.csv 400 3 "rk4 cloth: the trajectory is complete up to the last good step, every value finite"
expect_no_tmp "rk4 cloth"
last=$(tail -n 1 out.csv | cut -d, -f1)
check "rk4 cloth: stopped long before the end (last good step $last)" test "$last" -lt 120
expect_stderr_re 'psys: cloth\.json: the state became non-finite at step [0-9]+ \(from t = [0-9.e+-]+\), particle [0-9]+ \("sheet\[[0-9]+,[0-9]+\]"\); stopped at the last good state' \
    "rk4 cloth: one line naming step, time and particle"
expect_stderr_has "at step $((last + 1)) " "rk4 cloth: the message names the failing step (last good + 1)"
check "rk4 cloth: a pinned corner is not blamed (got: $(head -c 300 err.txt))" \
    sh -c '! grep -Eq "sheet\[(0|19),0\]" err.txt'

# ---- implicit-euler runs it (the sanitizer build is slow: a few steps here,
# the 5-second run with settling checks is test_implicit.cloth_hangs_and_settles) ----
psys run cloth.json --integrator implicit-euler --steps 3 --every 1 --out imp.csv --energy imp-e.csv
expect_rc 0 "implicit cloth: exit status"
expect_stdout_empty "implicit cloth"
expect_stderr_empty "implicit cloth (CG converged: no warning)"
expect_trajectory imp.csv 400 3 "implicit cloth: the trajectory is complete and finite"
expect_energy imp-e.csv "implicit cloth: the energy file"
expect_eq "0 1 2 3" "$(csv_steps_line imp.csv)" "implicit cloth: frames"
# the pinned corners (particles 0 and 19) never move, bit for bit
for i in 0 19; do
    expect_eq "$(awk -F, -v i=$i 'NR > 1 && $3 == i && $1 == 0 { print $4, $5, $6, $7, $8, $9 }' imp.csv)" \
        "$(awk -F, -v i=$i 'NR > 1 && $3 == i && $1 == 3 { print $4, $5, $6, $7, $8, $9 }' imp.csv)" \
        "implicit cloth: pinned particle $i is where it started, at rest"
done
y399=$(csv_field imp.csv 3 399 5)
check "implicit cloth: the free corner fell (y = $y399)" awk -v y="$y399" 'BEGIN { exit !(y < -0.005) }'
e0=$(energy_field imp-e.csv 0 5)
e3=$(energy_field imp-e.csv 3 5)
check "implicit cloth: no energy gained ($e0 -> $e3)" awk -v a="$e0" -v b="$e3" 'BEGIN { exit !(b <= a) }'

# ---- conjugate gradient stopped short: one warning line, the run completes ----
# (On the first step the flat, unstrained cloth meets gravity normal to it,
# which one CG iteration solves exactly; every later step stops short.)
cloth_scene capped.json implicit-euler 10 '"cg_max_iterations": 1,'
psys run capped.json --steps 10 --out capped.csv
expect_rc 0 "cg_max_iterations 1: the run completes"
expect_stdout_empty "cg_max_iterations 1"
expect_stderr_re 'psys: capped\.json: warning: conjugate gradient stopped short of cg_tolerance in 9 steps \(worst relative residual [0-9.]+(e[+-][0-9]+)?\); raise cg_max_iterations or lower dt' \
    "cg_max_iterations 1: the warning line"
expect_trajectory capped.csv 100 3 "cg_max_iterations 1: the trajectory is complete"
psys run capped.json --steps 10 --out capped-q.csv --quiet
expect_rc 0 "cg_max_iterations 1 --quiet"
expect_stderr_empty "cg_max_iterations 1 --quiet: no warning"
expect_same capped.csv capped-q.csv "cg_max_iterations 1: --quiet changes nothing else"
# the same scene with the default cap converges: no warning
cloth_scene uncapped.json implicit-euler 10 ""
psys run uncapped.json --steps 10 --out uncapped.csv
expect_rc 0 "default CG settings"
expect_stderr_empty "default CG settings: no warning"

# ---- validation of the scene keys (exit 2, one line, nothing written) ----
bad_key() { # JSON-FRAGMENT EXPECTED-MESSAGE
    printf '{"psys": 1, "integrator": "implicit-euler", %s, "particles": [{"x": [0, 0, 0]}]}\n' "$1" >bad.json
    psys check bad.json
    expect_rc 2 "check $1"
    expect_stderr "psys: bad.json: $2" "check $1"
    expect_stdout_empty "check $1"
    rm -f never.csv
    psys run bad.json --out never.csv
    expect_rc 2 "run $1"
    expect_stderr "psys: bad.json: $2" "run $1"
    expect_absent never.csv "run $1"
}
bad_key '"cg_max_iterations": 0' 'cg_max_iterations: must be an integer from 1 to 1e15 (got 0)'
bad_key '"cg_max_iterations": -1' 'cg_max_iterations: must be an integer from 1 to 1e15 (got -1)'
bad_key '"cg_max_iterations": 1.5' 'cg_max_iterations: must be an integer (got 1.5)'
bad_key '"cg_max_iterations": "many"' 'cg_max_iterations: must be an integer (got "many")'
bad_key '"cg_tolerance": 0' 'cg_tolerance: must be > 0 (got 0)'
bad_key '"cg_tolerance": -1' 'cg_tolerance: must be > 0 (got -1)'
bad_key '"cg_tolerance": "tight"' 'cg_tolerance: must be a number (got "tight")'
bad_key '"cg_tol": 1e-9' 'cg_tol: unknown key'

# ---- saving: written only when not default, exact round trips ----
# (12×12: more nodes than the multigrid's coarsest level, so the solve is not
# exact after one iteration and the iteration cap matters)
cat >small.json <<'EOF'
{"psys": 1, "dim": 3, "integrator": "implicit-euler", "dt": 0.01, "steps": 40,
 "cg_tolerance": 3.0000000000000001e-9, "cg_max_iterations": 7,
 "structures": [{"type": "cloth", "id": "patch", "size": [12, 12], "spacing": 0.1,
   "axes": [[1, 0, 0], [0, 0, 1]], "mass": 0.05, "ks": 200, "kd": 0.5, "pin": [[0, 0], [11, 0]]}],
 "forces": [{"type": "gravity"}, {"type": "drag", "kd": 0.01}]}
EOF
psys check small.json --save small-A.json
expect_rc 0 "check small --save"
psys check small-A.json --save small-B.json
expect_rc 0 "check small-A --save"
expect_same small-A.json small-B.json "saving a saved scene gives the same bytes"
check "the saved scene keeps cg_tolerance (got: $(grep cg_ small-A.json | tr -d '\n'))" \
    grep -Eq '"cg_tolerance":[[:space:]]*3e-09,?$' small-A.json
check "the saved scene keeps cg_max_iterations" grep -Eq '"cg_max_iterations":[[:space:]]*7,?$' small-A.json
psys run small.json --out run-S.csv
expect_rc 0 "run small"
psys run small-A.json --out run-A.csv
expect_rc 0 "run small-A"
expect_same run-S.csv run-A.csv "the scene and its saved form run bit for bit alike"
# the keys are used: with the defaults the run differs
grep -v '"cg_' small.json >small-default.json
psys run small-default.json --out run-D.csv
expect_rc 0 "run small with default CG settings"
check "cg_max_iterations 7 changes the run" sh -c '! cmp -s run-S.csv run-D.csv'
# defaults are not written
psys check small-default.json --save small-D.json
expect_rc 0 "check small-default --save"
check "default CG settings are not written" sh -c '! grep -q "cg_" small-D.json'

expect_no_tmp "whole test"
finish
