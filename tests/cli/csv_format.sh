# Output files and run length (docs/cli.md "Trajectory CSV", "Energy CSV";
# docs/semantics.md "Steps and frames", "Output frames"): headers, one row per particle per frame,
# frame 0 and the last step always present, --every, --steps, --duration
# ending exactly at T, %.17g numbers, "-" for standard input, flags over
# scene values, the scene's output block, and energies against hand values.
. "$(dirname "$0")/lib.sh"

# ---------------------------------------------------------------- scenes

# One particle at rest at height 2, mass 3, under g = (0, -9.81), dt 0.1.
cat >drop.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.1, "steps": 10,
 "particles": [{"id": "ball", "x": [0, 2], "mass": 3}],
 "forces": [{"type": "gravity", "g": [0, -9.81]}]}
EOF

# Three particles, 2-D, springs and a fixed particle.
cat >three2.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.01, "steps": 4,
 "particles": [{"id": "p", "x": [0, 0], "fixed": true},
               {"id": "q", "x": [1, 0], "v": [0, 1], "mass": 0.5},
               {"x": [1, 1], "mass": 2}],
 "forces": [{"type": "gravity", "g": [0, -9.81]}, {"type": "drag", "kd": 0.1},
            {"type": "spring", "a": "p", "b": "q", "ks": 100, "kd": 0.5},
            {"type": "spring", "a": 1, "b": 2, "ks": 50, "rest": 0.8}]}
EOF

# Two particles, 3-D.
cat >two3.json <<'EOF'
{"psys": 1, "dim": 3, "dt": 0.01, "steps": 4,
 "particles": [{"x": [0, 0, 1], "v": [1, 0, 0]}, {"x": [0, 1, 1], "v": [0, 0, 1], "mass": 2}],
 "forces": [{"type": "gravity", "g": [0, 0, -9.81]},
            {"type": "spring", "a": 0, "b": 1, "ks": 20}]}
EOF

# ---------------------------------------------------------------- headers, rows, frames

psys run three2.json --out t2.csv --energy e2.csv
expect_rc 0 "run three2"
expect_stderr_empty "run three2 (no progress bar, no message when not on a terminal)"
expect_stdout_empty "run three2"
expect_eq 'step,t,i,x,y,vx,vy' "$(head -n 1 t2.csv)" "2-D trajectory header"
expect_trajectory t2.csv 3 2 "2-D trajectory"
expect_eq 16 "$(wc -l <t2.csv)" "2-D: header + 3 particles x 5 frames"
expect_eq '0 1 2 3 4' "$(csv_steps_line t2.csv)" "2-D: frames 0..4 with --steps 4 (from the scene)"
expect_eq '0,0,0,0,0,0,0' "$(sed -n 2p t2.csv)" "frame 0 row of the fixed particle is the initial state"
expect_eq '0,0,1,1,0,0,1' "$(sed -n 3p t2.csv)" "frame 0 row of particle 1 is the initial state"
expect_eq '0,0,2,1,1,0,0' "$(sed -n 4p t2.csv)" "frame 0 row of particle 2 is the initial state"
expect_eq 'step,t,kinetic,potential,total' "$(head -n 1 e2.csv)" "energy header"
expect_energy e2.csv "energy CSV"
expect_eq "$(csv_steps_line t2.csv)" "$(awk -F, 'NR > 1 { print $1 }' e2.csv | tr '\n' ' ' | sed 's/ $//')" \
    "energy CSV has one row per trajectory frame"
# the fixed particle does not move
expect_eq '4,0.040000000000000001,0,0,0,0,0' "$(sed -n 14p t2.csv)" "fixed particle stays put"

psys run two3.json --out t3.csv
expect_rc 0 "run two3"
expect_eq 'step,t,i,x,y,z,vx,vy,vz' "$(head -n 1 t3.csv)" "3-D trajectory header"
expect_trajectory t3.csv 2 3 "3-D trajectory"
expect_eq 11 "$(wc -l <t3.csv)" "3-D: header + 2 particles x 5 frames"
expect_eq '0,0,0,0,0,1,1,0,0' "$(sed -n 2p t3.csv)" "3-D frame 0 row of particle 0"
expect_eq '0,0,1,0,1,1,0,0,1' "$(sed -n 3p t3.csv)" "3-D frame 0 row of particle 1"

# ---------------------------------------------------------------- --every

psys run drop.json --steps 10 --every 3 --out e3.csv --energy en3.csv
expect_rc 0 "--steps 10 --every 3"
expect_eq '0 3 6 9 10' "$(csv_steps_line e3.csv)" "--steps 10 --every 3: frames at 0,3,6,9 and the last step 10"
expect_eq '0 3 6 9 10' "$(awk -F, 'NR > 1 { print $1 }' en3.csv | tr '\n' ' ' | sed 's/ $//')" \
    "--every applies to the energy CSV too"
expect_trajectory e3.csv 1 2 "--every 3 trajectory"

psys run drop.json --steps 9 --every 3 --out e9.csv
expect_eq '0 3 6 9' "$(csv_steps_line e9.csv)" "--steps 9 --every 3: the last step is written once"
expect_trajectory e9.csv 1 2 "--steps 9 --every 3 trajectory"

psys run drop.json --steps 2 --every 5 --out e2b.csv
expect_eq '0 2' "$(csv_steps_line e2b.csv)" "--steps 2 --every 5: frame 0 and the last step"

psys run drop.json --steps 0 --out e0.csv --energy en0.csv
expect_rc 0 "--steps 0"
expect_eq '0' "$(csv_steps_line e0.csv)" "--steps 0: only frame 0"
expect_eq 2 "$(wc -l <en0.csv)" "--steps 0: energy header + frame 0"

# The rows of an --every run are exactly the matching rows of an every-1 run.
psys run drop.json --steps 10 --out all.csv
awk -F, 'NR == 1 || $1 % 3 == 0 || $1 == 10' all.csv >all-every3.csv
expect_same e3.csv all-every3.csv "--every 3 rows are the every-1 rows of steps 0,3,6,9,10"

# ---------------------------------------------------------------- --steps, %.17g times

psys run drop.json --steps 7 --out s7.csv
expect_eq '0 1 2 3 4 5 6 7' "$(csv_steps_line s7.csv)" "--steps 7 takes 7 steps"
expect_eq '0.30000000000000004' "$(csv_field s7.csv 3 0 2)" "t of step 3 with dt 0.1 is printed %.17g"
expect_eq '0.10000000000000001' "$(csv_field s7.csv 1 0 2)" "t of step 1 with dt 0.1 is printed %.17g"
expect_eq '0.70000000000000007' "$(csv_field s7.csv 7 0 2)" "t of step 7 with dt 0.1 is 7*0.1 printed %.17g"
# Constant acceleration: RK4 is exact up to rounding; y = 2 - g t^2 / 2.
expect_near "$(csv_field s7.csv 3 0 5)" 1.55855 1e-13 "y at t = 0.3 (free fall)"
expect_near "$(csv_field s7.csv 3 0 7)" -2.943 1e-13 "vy at t = 0.3 (free fall)"

# ---------------------------------------------------------------- --duration

# dt 0.1 does not divide 0.25: 3 steps, the last one shortened, ending at t = 0.25 exactly.
psys run drop.json --duration 0.25 --out d25.csv
expect_rc 0 "--duration 0.25"
expect_eq '0 1 2 3' "$(csv_steps_line d25.csv)" "--duration 0.25 with dt 0.1: ceil(2.5) = 3 steps"
expect_eq '0.25' "$(csv_field d25.csv 3 0 2)" "--duration 0.25 ends exactly at t = 0.25"
expect_near "$(csv_field d25.csv 3 0 5)" 1.6934375 1e-13 "y at t = 0.25: the last step was shortened to 0.05"
expect_near "$(csv_field d25.csv 3 0 7)" -2.4525 1e-13 "vy at t = 0.25"

# 0.3/0.1 = 2.9999999999999996 and 1.1/0.1 = 11.000000000000002 in doubles:
# the tolerance of §3a makes them 3 and 11 steps.
psys run drop.json --duration 0.3 --out d3.csv
expect_eq '0 1 2 3' "$(csv_steps_line d3.csv)" "--duration 0.3 with dt 0.1: 3 steps"
expect_eq '0.29999999999999999' "$(csv_field d3.csv 3 0 2)" "--duration 0.3 ends exactly at 0.3"
psys run drop.json --duration 1.1 --out d11.csv
expect_eq '0 1 2 3 4 5 6 7 8 9 10 11' "$(csv_steps_line d11.csv)" "--duration 1.1 with dt 0.1: 11 steps, not 12"
expect_eq '1.1000000000000001' "$(csv_field d11.csv 11 0 2)" "--duration 1.1 ends exactly at 1.1"
psys run drop.json --duration 1 --every 4 --out d1.csv
expect_eq '0 4 8 10' "$(csv_steps_line d1.csv)" "--duration 1 --every 4: frames 0,4,8 and the last step 10"
expect_eq '1' "$(csv_field d1.csv 10 0 2)" "--duration 1 ends at t = 1"

# default duration 1.0 and default dt 0.001: 1000 steps
printf '{"psys": 1, "particles": [{"x": [0, 0, 0]}]}' >defaults.json
psys run defaults.json --every 250 --out def.csv
expect_rc 0 "defaults"
expect_eq '0 250 500 750 1000' "$(csv_steps_line def.csv)" "default dt 0.001 and duration 1: 1000 steps"
expect_eq '1' "$(csv_field def.csv 1000 0 2)" "default run ends at t = 1"
expect_eq 'step,t,i,x,y,z,vx,vy,vz' "$(head -n 1 def.csv)" "default dim is 3"

# ---------------------------------------------------------------- every number is %.17g

for f in t2.csv t3.csv e3.csv d25.csv d11.csv; do
    check "$f: numbers printed with %.17g" trajectory_ok "$f" "$(awk -F, 'NR > 1 && $1 == 0' "$f" | wc -l)" \
        "$(head -n 1 "$f" | awk -F, '{ print (NF == 7) ? 2 : 3 }')"
done

# ---------------------------------------------------------------- "-" is standard input

psys_in drop.json run - --steps 10 --every 3 --out stdin.csv --energy stdin-en.csv
expect_rc 0 "run - (scene on stdin)"
expect_same e3.csv stdin.csv "run - gives the same trajectory as the file"
expect_same en3.csv stdin-en.csv "run - gives the same energies as the file"
psys_in drop.json check -
expect_rc 0 "check -"
check "check - names the scene <stdin>" grep -qx 'scene: <stdin>' out.txt

# ---------------------------------------------------------------- flags override the scene

cat >withoutput.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.1, "steps": 4, "integrator": "rk4",
 "particles": [{"x": [0, 2], "mass": 3}],
 "forces": [{"type": "gravity", "g": [0, -9.81]}],
 "output": {"every": 2, "trajectory": "scene-traj.csv", "energy": "scene-energy.csv"}}
EOF

# the scene's output block is used when no flags are given
psys run withoutput.json
expect_rc 0 "scene output block"
expect_exists scene-traj.csv "scene output block: trajectory"
expect_exists scene-energy.csv "scene output block: energy"
expect_eq '0 2 4' "$(csv_steps_line scene-traj.csv)" "scene output.every 2 with scene steps 4"
expect_eq '0 2 4' "$(awk -F, 'NR > 1 { print $1 }' scene-energy.csv | tr '\n' ' ' | sed 's/ $//')" \
    "scene output.energy written every 2 steps"
expect_eq '0.40000000000000002' "$(csv_field scene-traj.csv 4 0 2)" "scene dt 0.1 used"
rm -f scene-traj.csv scene-energy.csv

# --out, --energy, --every, --steps, --dt and --integrator override
psys run withoutput.json --out flag-traj.csv --energy flag-energy.csv --every 1 --steps 2 --dt 0.05 --integrator euler
expect_rc 0 "flags override"
expect_absent scene-traj.csv "--out overrides output.trajectory"
expect_absent scene-energy.csv "--energy overrides output.energy"
expect_eq '0 1 2' "$(csv_steps_line flag-traj.csv)" "--every 1 --steps 2 override the scene"
expect_eq '0.050000000000000003' "$(csv_field flag-traj.csv 1 0 2)" "--dt 0.05 overrides the scene"
# explicit Euler from rest: the first step does not move the particle
expect_eq '1,0.050000000000000003,0,0,2,0' "$(sed -n 3p flag-traj.csv | cut -d, -f1-6)" \
    "--integrator euler overrides the scene (x1 = x0)"
expect_near "$(csv_field flag-traj.csv 1 0 7)" -0.4905 1e-14 "--integrator euler: v1 = v0 + h g"
rm -f scene-traj.csv scene-energy.csv

# --duration overrides the scene's steps; --steps overrides the scene's duration
psys run withoutput.json --duration 0.25 --out dur.csv
expect_eq '0 2 3' "$(csv_steps_line dur.csv)" "--duration 0.25 replaces the scene's steps 4 (every 2 from the scene)"
expect_eq '0.25' "$(csv_field dur.csv 3 0 2)" "--duration 0.25 over scene steps ends at 0.25"
expect_exists scene-energy.csv "output.energy still used when only --out is given"
rm -f scene-traj.csv scene-energy.csv
sed 's/"steps": 4/"duration": 0.5/' withoutput.json >withduration.json
psys run withduration.json --steps 3 --every 1 --out st.csv
expect_eq '0 1 2 3' "$(csv_steps_line st.csv)" "--steps 3 replaces the scene's duration"
rm -f scene-traj.csv scene-energy.csv
psys run withduration.json --every 1 --out sd.csv
expect_eq '0 1 2 3 4 5' "$(csv_steps_line sd.csv)" "scene duration 0.5 with dt 0.1: 5 steps"

# ---------------------------------------------------------------- energies against hand values

# drop.json: KE 0, U = m g y = 3 * 9.81 * 2 = 58.86.
psys run drop.json --steps 10 --energy drop-e.csv
expect_rc 0 "energy run"
expect_eq 0 "$(energy_field drop-e.csv 0 3)" "kinetic energy at rest is 0"
expect_near "$(energy_field drop-e.csv 0 4)" 58.86 1e-14 "potential m*9.81*y = 58.86"
expect_near "$(energy_field drop-e.csv 0 5)" 58.86 1e-14 "total = 58.86"
# after 1 s of free fall: v = 9.81, y = 2 - 9.81/2
expect_near "$(energy_field drop-e.csv 10 3)" "$(awk 'BEGIN { printf "%.17g", 0.5 * 3 * 9.81 * 9.81 }')" 1e-12 \
    "kinetic energy after 1 s of free fall"
expect_near "$(energy_field drop-e.csv 10 4)" "$(awk 'BEGIN { printf "%.17g", 3 * 9.81 * (2 - 9.81 / 2) }')" 1e-12 \
    "potential energy after 1 s of free fall"
expect_near "$(energy_field drop-e.csv 10 5)" 58.86 1e-12 "free fall conserves energy (RK4 exact)"

# Kinetic + gravity (free particles only) + springs, by hand:
#   free "a": m 2, v (3, 4), y 1      -> KE 25,  U 2*9.81*1 = 19.62
#   fixed "f": m 5 at y 10            -> nothing (fixed particles are not counted)
#   free "b": m 1 at rest, y -1       -> U 1*9.81*(-1) = -9.81
#   spring a-b: length sqrt(4+4) with rest 1, ks 10  -> 5 (sqrt 8 - 1)^2
#   spring f-a: length 9, default rest (= 9): 0
cat >energy.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.001, "steps": 1,
 "particles": [{"id": "a", "x": [1, 1], "v": [3, 4], "mass": 2},
               {"id": "f", "x": [1, 10], "mass": 5, "fixed": true},
               {"id": "b", "x": [-1, -1]}],
 "forces": [{"type": "gravity", "g": [0, -9.81]},
            {"type": "spring", "a": "a", "b": "b", "ks": 10, "kd": 3, "rest": 1},
            {"type": "spring", "a": "f", "b": "a", "ks": 7}]}
EOF
psys run energy.json --energy en.csv
expect_rc 0 "energy scene"
pe=$(awk 'BEGIN { s = sqrt(8) - 1; printf "%.17g", 19.62 - 9.81 + 5 * s * s }')
expect_near "$(energy_field en.csv 0 3)" 25 1e-14 "kinetic: free particles, 1/2 m v^2"
expect_near "$(energy_field en.csv 0 4)" "$pe" 1e-13 "potential: gravity of free particles + 1/2 ks (|l| - r)^2"
expect_near "$(energy_field en.csv 0 5)" "$(awk -v p="$pe" 'BEGIN { printf "%.17g", 25 + p }')" 1e-13 \
    "total = kinetic + potential"
psys check energy.json
expect_rc 0 "check energy.json"
expect_eq "energy: $(energy_field en.csv 0 5)" "$(grep '^energy: ' out.txt)" "check's energy is the CSV's frame-0 total"

# 3-D gravity along z: U = m g z
printf '{"psys": 1, "particles": [{"x": [5, 7, 2], "mass": 3}], "forces": [{"type": "gravity", "g": [0, 0, -9.81]}], "steps": 1}' >g3.json
psys run g3.json --energy g3e.csv
expect_near "$(energy_field g3e.csv 0 4)" 58.86 1e-14 "3-D potential m*9.81*z = 58.86"

expect_no_tmp "whole test"
finish
