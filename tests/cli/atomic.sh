# Output files are written under a temporary name and renamed when complete
# (docs/cli.md "How files are written"; docs/semantics.md "Failed and interrupted
# runs", "Checkpoints"):
#   - a run that cannot start (exit 2) creates, truncates and replaces nothing,
#     including when an output directory does not exist;
#   - an existing output file keeps its old content until the run is complete;
#   - SIGINT/SIGTERM stop a run with status 128+signal, files holding whole
#     frames up to the interrupted step, and --checkpoint written.
# shellcheck disable=SC2034  # RC is read by the helpers in lib.sh
. "$(dirname "$0")/lib.sh"

cat >scene.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.01, "steps": 20,
 "particles": [{"id": "p", "x": [0, 0], "fixed": true},
               {"id": "b", "x": [1, 0], "v": [0, 0.5], "mass": 0.5},
               {"x": [1, 1], "mass": 2}],
 "forces": [{"type": "gravity", "g": [0, -9.81]}, {"type": "drag", "kd": 0.1},
            {"type": "spring", "a": "p", "b": "b", "ks": 100, "kd": 0.5},
            {"type": "spring", "a": 1, "b": 2, "ks": 50, "rest": 0.8}]}
EOF

# dir_listing: every file under the working directory, sorted.
dir_listing() { find . -mindepth 1 ! -name out.txt ! -name err.txt | LC_ALL=C sort; }

# ---------------------------------------------------------------- output directory does not exist

# cannot_start LABEL MESSAGE ARGS...: exit 2, exactly "psys: MESSAGE", and no
# file created anywhere (compared with the listing before).
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

cannot_start "--out into a missing directory" \
    '--out nodir/traj.csv: cannot create: No such file or directory' \
    run scene.json --out nodir/traj.csv --energy energy.csv --checkpoint ck.json
cannot_start "--energy into a missing directory" \
    '--energy nodir/energy.csv: cannot create: No such file or directory' \
    run scene.json --out traj.csv --energy nodir/energy.csv --checkpoint ck.json
# The checkpoint is written at the end, but a run whose checkpoint cannot be
# written cannot do what was asked: it must fail before it starts, not after
# simulating and writing the other files.
cannot_start "--checkpoint into a missing directory" \
    '--checkpoint nodir/ck.json: cannot create: No such file or directory' \
    run scene.json --out traj.csv --energy energy.csv --checkpoint nodir/ck.json
cannot_start "--out into a path under a regular file" \
    '--out scene.json/traj.csv: cannot create: Not a directory' \
    run scene.json --out scene.json/traj.csv
psys check scene.json --save nodir/saved.json
expect_rc 2 "check --save into a missing directory"
expect_absent nodir "check --save into a missing directory"
check "check --save into a missing directory: message (got: $(cat err.txt))" \
    grep -qx 'psys: --save nodir/saved.json: cannot create: No such file or directory' err.txt
expect_no_tmp "missing directories"

# ---------------------------------------------------------------- replaced only when complete

# A successful run replaces the old content with a complete new file, with
# the usual permissions (umask 022 -> 644).
sentinel traj.csv
sentinel energy.csv
sentinel ck.json
psys run scene.json --out traj.csv --energy energy.csv --checkpoint ck.json
expect_rc 0 "run over existing files"
check "old trajectory content is gone" sh -c '! grep -q "pre-existing" traj.csv'
check "old energy content is gone" sh -c '! grep -q "pre-existing" energy.csv'
check "old checkpoint content is gone" sh -c '! grep -q "pre-existing" ck.json'
expect_trajectory traj.csv 3 2 "new trajectory is complete"
expect_energy energy.csv "new energy file is complete"
expect_eq 20 "$(tail -n 1 traj.csv | cut -d, -f1)" "new trajectory ends at the last step"
expect_eq 644 "$(stat -c %a traj.csv)" "trajectory file mode follows the umask"
expect_eq 644 "$(stat -c %a energy.csv)" "energy file mode follows the umask"
expect_eq 644 "$(stat -c %a ck.json)" "checkpoint file mode follows the umask"
expect_no_tmp "successful run"

# A bad scene or a bad flag leaves the old files untouched.
sentinel traj.csv
sentinel energy.csv
sentinel ck.json
printf '{"psys": 1, "dim": 2, "dt": -1}' >bad.json
psys run bad.json --out traj.csv --energy energy.csv --checkpoint ck.json
expect_rc 2 "bad scene"
expect_untouched traj.csv "bad scene: trajectory"
expect_untouched energy.csv "bad scene: energy"
expect_untouched ck.json "bad scene: checkpoint"
psys run scene.json --out traj.csv --energy energy.csv --checkpoint ck.json --every 0
expect_rc 2 "bad flag"
expect_untouched traj.csv "bad flag: trajectory"
expect_untouched energy.csv "bad flag: energy"
expect_untouched ck.json "bad flag: checkpoint"
expect_no_tmp "bad scene / bad flag"

# While a long run is going, the final names still hold the old content.
cat >long.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.001, "steps": 1000000000000,
 "particles": [{"id": "p", "x": [0, 0], "fixed": true},
               {"id": "b", "x": [1, 0], "v": [0, 0.5], "mass": 0.5},
               {"x": [1, 1], "mass": 2}],
 "forces": [{"type": "gravity", "g": [0, -9.81]}, {"type": "drag", "kd": 0.1},
            {"type": "spring", "a": "p", "b": "b", "ks": 100, "kd": 0.5},
            {"type": "spring", "a": 1, "b": 2, "ks": 50, "rest": 0.8}]}
EOF
sentinel traj.csv
sentinel energy.csv
"$PSYS" run long.json --every 50000 --out traj.csv --energy energy.csv >bg-out.txt 2>bg-err.txt </dev/null &
pid=$!
wait_caught "$pid" TERM && sleep 0.7
expect_untouched traj.csv "during a run, the trajectory's final name"
expect_untouched energy.csv "during a run, the energy file's final name"
kill -TERM "$pid" 2>/dev/null
wait "$pid"
rc=$?
expect_eq 143 "$rc" "SIGTERM: exit status 128+15"
expect_trajectory traj.csv 3 2 "SIGTERM: trajectory whole frames"
expect_energy energy.csv "SIGTERM: energy file complete"
check "SIGTERM: old trajectory content replaced" sh -c '! grep -q "pre-existing" traj.csv'
expect_no_tmp "SIGTERM"

# ---------------------------------------------------------------- SIGINT

rm -f traj.csv energy.csv ck.json
sentinel traj.csv
timeout --preserve-status -s INT 1 "$PSYS" run long.json --every 100000 \
    --out traj.csv --energy energy.csv --checkpoint ck.json >out.txt 2>err.txt </dev/null
RC=$?
expect_rc 130 "SIGINT: exit status 128+2"
expect_trajectory traj.csv 3 2 "SIGINT: trajectory has whole frames"
expect_energy energy.csv "SIGINT: energy file is complete"
expect_exists ck.json "SIGINT: --checkpoint written"
expect_no_tmp "SIGINT"
last=$(tail -n 1 traj.csv | cut -d, -f1)
tlast=$(tail -n 1 traj.csv | cut -d, -f2)
check "SIGINT: the run was stopped early (last frame $last)" test "$last" -lt 1000000000000
check "SIGINT: the run got somewhere (last frame $last)" test "$last" -gt 0
expect_eq "$last" "$(tail -n 1 energy.csv | cut -d, -f1)" "SIGINT: energy file ends at the same step"
expect_stderr_has "interrupted at step $last" "SIGINT: the message names the interrupted step"
expect_stderr_has "t = $tlast" "SIGINT: the message names the time"
# frames: 0, multiples of 100000, then the interrupted step (if not a multiple)
want=$(awk -v l="$last" 'BEGIN { for (s = 0; s < l; s += 100000) printf "%d ", s; printf "%d", l }')
expect_eq "$want" "$(csv_steps_line traj.csv)" "SIGINT: frames are 0, every 100000, and the interrupted step"

# the checkpoint holds the interrupted state: resuming starts from the last frame
psys run --resume ck.json --steps 3 --every 1 --out resumed.csv
expect_rc 0 "resume after SIGINT"
expect_eq "$(tail -n 3 traj.csv)" "$(sed -n 2,4p resumed.csv)" "resume after SIGINT starts at the interrupted state"
expect_eq $((last + 3)) "$(tail -n 1 resumed.csv | cut -d, -f1)" "resume after SIGINT continues the step count"

# --quiet: no interruption notice
timeout --preserve-status -s INT 0.5 "$PSYS" run long.json --every 100000 --quiet --out q.csv >out.txt 2>err.txt </dev/null
RC=$?
expect_rc 130 "SIGINT --quiet: exit status"
expect_stderr_empty "SIGINT --quiet: no notice"
expect_trajectory q.csv 3 2 "SIGINT --quiet: whole frames"

# the scene's own output block is atomic too
cat >withoutput.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.01, "steps": 5,
 "particles": [{"x": [0, 0]}],
 "output": {"trajectory": "nodir/t.csv"}}
EOF
cannot_start "output.trajectory into a missing directory" \
    'output.trajectory nodir/t.csv: cannot create: No such file or directory' run withoutput.json

expect_no_tmp "whole test"
finish
