# Numerical guard rails (docs/trust.md): an explicit solver run with dt above
# the stability estimate 2/omega_max of the stiffest spring (omega_max² =
# max 2 ks (1/m_a + 1/m_b), src/sim/stability.c) gets one warning on stderr that
# suggests implicit-euler or a smaller dt; none for implicit-euler or rk45,
# none with --quiet, none below the limit. And the estimate is right where it
# matters: the highest mode of a free chain (exactly what it bounds) is
# stable just below 2/omega_max and blows up just above it.
# shellcheck disable=SC2034  # RC is read by the helpers in lib.sh
. "$(dirname "$0")/lib.sh"

# chain N KS DT: N free unit masses, springs of rest 0.1 between neighbours,
# started in the zig-zag (highest) longitudinal mode. omega_max = sqrt(2·ks·2).
chain() {
    local n=$1 ks=$2 dt=$3
    {
        printf '{"psys": 1, "dim": 2, "integrator": "verlet", "dt": %s, "steps": 3000,\n "particles": [' "$dt"
        for ((i = 0; i < n; i++)); do
            [ "$i" -gt 0 ] && printf ', '
            printf '{"x": [%s, 0]}' "$(awk -v i="$i" 'BEGIN { printf "%.6f", i * 0.1 + (i % 2 ? 0.001 : -0.001) }')"
        done
        printf '],\n "forces": ['
        for ((i = 0; i + 1 < n; i++)); do
            [ "$i" -gt 0 ] && printf ', '
            printf '{"type": "spring", "a": %d, "b": %d, "ks": %s, "rest": 0.1}' "$i" $((i + 1)) "$ks"
        done
        printf ']}\n'
    }
}

# ks = 100, m = 1: omega_max = sqrt(2·100·2) = 20, limit 2/20 = 0.1.
chain 50 100 0.105 >above.json
chain 50 100 0.095 >below.json

psys run above.json --out above.csv
expect_rc 1 "verlet at dt = 1.05 × 2/omega_max: the highest mode blows up"
warn='psys: above.json: warning: dt = 0.105 is above the stability limit 2/omega_max = 0.1 of verlet for the stiffest spring (omega_max = 20 rad/s); the run may blow up: use --integrator implicit-euler, or --dt 0.1 or smaller'
expect_eq "$warn" "$(head -n 1 err.txt)" "the warning, first, before the failure"
expect_eq 1 "$(grep -c 'warning: dt' err.txt)" "the warning is given once"
expect_stderr_has "became non-finite" "and then the failure"

psys run below.json --out below.csv
expect_rc 0 "verlet at dt = 0.95 × 2/omega_max: stable"
expect_stderr_empty "no warning below the limit"
maxdev=$(awk -F, 'NR > 1 { d = $4 - int($3) * 0.1; if (d < 0) d = -d; if (d > m) m = d } END { printf "%.6f", m }' below.csv)
check "below the limit the zig-zag stays small (max displacement $maxdev)" awk -v m="$maxdev" 'BEGIN { exit !(m < 0.01) }'

for integ in implicit-euler rk45; do
    psys run above.json --integrator "$integ" --steps 20
    expect_rc 0 "$integ above the explicit limit"
    expect_stderr_empty "$integ: no stability warning"
done
for integ in euler midpoint rk4 symplectic-euler; do
    psys run above.json --integrator "$integ" --steps 2
    expect_rc 0 "$integ, 2 steps"
    expect_stderr_has "warning: dt = 0.105 is above the stability limit 2/omega_max = 0.1 of $integ" "$integ: warned"
done
psys run above.json --steps 2 --quiet
expect_rc 0 "--quiet run"
expect_stderr_empty "--quiet: no warning"
psys run below.json --dt 0.2 --steps 2
expect_stderr_has "warning: dt = 0.2 is above" "--dt on the command line is the dt checked"

# Fixed and controlled ends move no mass: a spring to an anchor counts one particle.
cat >anchor.json <<'EOF'
{"psys": 1, "dim": 2, "integrator": "rk4", "dt": 0.15, "steps": 2,
 "particles": [{"x": [0, 0], "fixed": true}, {"x": [1, 0], "mass": 2},
               {"x": [3, 0], "control": {"type": "oscillate", "center": [3, 0], "direction": [1, 0], "amplitude": 0.1, "omega": 1}}],
 "forces": [{"type": "spring", "a": 0, "b": 1, "ks": 100}, {"type": "spring", "a": 0, "b": 2, "ks": 1e9}]}
EOF
# omega_max² = 2·100·(1/2) = 100: limit 0.2; the 1e9 spring joins two unmoved particles.
psys run anchor.json
expect_rc 0 "anchored spring"
expect_stderr_empty "dt 0.15 < 0.2: no warning (the anchor-to-motor spring moves nothing)"
psys run anchor.json --dt 0.25
expect_stderr_has "2/omega_max = 0.2 of rk4" "dt 0.25 > 0.2: warned"

expect_no_tmp "whole test"
finish
