# Shared helpers for the psys command-line contract tests (docs/scene-format.md,
# docs/cli.md, docs/semantics.md).
#
# Each test script is run as   bash tests/cli/NAME.sh /path/to/psys /path/to/source-root
# and sources this file first. It then works in a fresh temporary directory
# (removed on exit), records every failed check, and calls `finish` at the end,
# which exits 0 when every check passed and 1 otherwise.
#
# Only bash, coreutils, grep, sed, awk, cmp and diff are used.

set -u

if [ $# -lt 1 ] || [ ! -x "$1" ]; then
    echo "usage: bash $0 /path/to/psys [/path/to/source-root]" >&2
    exit 2
fi
PSYS=$(cd "$(dirname "$1")" && pwd)/$(basename "$1")
SRC=${2:-}
if [ -n "$SRC" ]; then
    SRC=$(cd "$SRC" && pwd)
fi

WORK=$(mktemp -d "${TMPDIR:-/tmp}/psys-cli.XXXXXX") || exit 2
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 2
umask 022

FAILS=0
CHECKS=0
TEST_NAME=$(basename "$0" .sh)

# fail MESSAGE...: record a failed check (and say what failed).
fail() {
    FAILS=$((FAILS + 1))
    echo "FAIL [$TEST_NAME]: $*"
}

# ok: record a passed check.
ok() { CHECKS=$((CHECKS + 1)); }

# check COND-DESCRIPTION -- command...: run the command; a non-zero status fails.
check() {
    local what=$1
    shift
    if "$@"; then ok; else fail "$what"; fi
}

# finish: print the summary and exit.
finish() {
    if [ "$FAILS" -gt 0 ]; then
        echo "$TEST_NAME: $FAILS check(s) failed, $CHECKS passed"
        exit 1
    fi
    echo "$TEST_NAME: all $CHECKS checks passed"
    exit 0
}

# psys ARGS...: run the program with stdout in out.txt and stderr in err.txt;
# its exit status is left in RC. Standard input is /dev/null unless redirected
# by the caller with psys_in.
RC=0
psys() {
    "$PSYS" "$@" >out.txt 2>err.txt </dev/null
    RC=$?
}

# psys_in FILE ARGS...: as psys, with standard input read from FILE.
psys_in() {
    local in=$1
    shift
    "$PSYS" "$@" >out.txt 2>err.txt <"$in"
    RC=$?
}

# expect_rc N LABEL: the last psys call exited with status N.
expect_rc() {
    if [ "$RC" -eq "$1" ]; then
        ok
    else
        fail "$2: exit status $RC, expected $1 (stderr: $(head -c 600 err.txt))"
    fi
}

# expect_stderr LINE LABEL: standard error is exactly that one line.
expect_stderr() {
    if printf '%s\n' "$1" | cmp -s - err.txt; then
        ok
    else
        fail "$2: stderr is not the expected line
      expected: $1
      got:      $(head -c 600 err.txt)"
    fi
}

# expect_stderr_re ERE LABEL: standard error is one line matching the
# extended regular expression (anchored at both ends).
expect_stderr_re() {
    if [ "$(wc -l <err.txt)" -eq 1 ] && grep -Eq "^($1)\$" err.txt; then
        ok
    else
        fail "$2: stderr does not match
      expected (regex): $1
      got:              $(head -c 600 err.txt)"
    fi
}

# expect_stderr_has TEXT LABEL: standard error contains TEXT (fixed string).
expect_stderr_has() {
    if grep -Fq -- "$1" err.txt; then
        ok
    else
        fail "$2: stderr does not contain \"$1\" (got: $(head -c 600 err.txt))"
    fi
}

# expect_stdout_empty LABEL / expect_stderr_empty LABEL
expect_stdout_empty() {
    if [ -s out.txt ]; then fail "$1: stdout is not empty (got: $(head -c 300 out.txt))"; else ok; fi
}
expect_stderr_empty() {
    if [ -s err.txt ]; then fail "$1: stderr is not empty (got: $(head -c 300 err.txt))"; else ok; fi
}

# expect_same FILE1 FILE2 LABEL: byte-identical files.
expect_same() {
    if [ ! -f "$1" ]; then
        fail "$3: $1 does not exist"
    elif [ ! -f "$2" ]; then
        fail "$3: $2 does not exist"
    elif cmp -s "$1" "$2"; then
        ok
    else
        fail "$3: $1 and $2 differ:
$(diff "$1" "$2" | head -n 8)"
    fi
}

# expect_exists FILE LABEL / expect_absent FILE LABEL
expect_exists() {
    if [ -f "$1" ]; then ok; else fail "$2: $1 was not written"; fi
}
expect_absent() {
    if [ -e "$1" ]; then fail "$2: $1 exists but should not"; else ok; fi
}

# expect_eq EXPECTED GOT LABEL: equal strings.
expect_eq() {
    if [ "$1" = "$2" ]; then
        ok
    else
        fail "$3: expected \"$1\", got \"$2\""
    fi
}

# expect_no_tmp LABEL [DIR]: no temporary output file (*.psys-tmp-*) is left.
expect_no_tmp() {
    local dir=${2:-.}
    local left
    left=$(find "$dir" -name '*.psys-tmp-*' 2>/dev/null | head -n 5)
    if [ -n "$left" ]; then
        fail "$1: temporary files left behind: $left"
    else
        ok
    fi
}

# wait_caught PID SIG: wait until the background psys PID catches SIG (its
# handler is installed: SigCgt in /proc/PID/status). A script's background
# job starts with SIGINT ignored, so a SIGINT sent before psys installs its
# handler is lost and the run goes on for ever; a SIGTERM kills it without
# its files. After 60 s (or if PID ends first): a failed check, PID killed.
wait_caught() {
    local pid=$1 sig=$2 num mask i
    num=$(kill -l "$sig")
    for ((i = 0; i < 600; i++)); do
        mask=$(awk '/^SigCgt:/ { print $2 }' "/proc/$pid/status" 2>/dev/null)
        [ -n "$mask" ] || break
        # psys itself, not a shell that has yet to exec it
        if [ "$(cat "/proc/$pid/comm" 2>/dev/null)" = psys ] && (((16#$mask >> (num - 1)) & 1)); then
            ok
            return 0
        fi
        sleep 0.1
    done
    fail "psys (pid $pid) did not catch SIG$sig within 60 s"
    kill -KILL "$pid" 2>/dev/null
    return 1
}

# sentinel FILE: give FILE a recognisable pre-existing content (and keep a copy).
sentinel() {
    printf 'pre-existing content of %s\nmust survive a run that cannot start\n' "$1" >"$1"
    cp "$1" "$1.orig"
}

# expect_untouched FILE LABEL: FILE still holds its sentinel content.
expect_untouched() {
    if [ ! -f "$1" ]; then
        fail "$2: pre-existing $1 was removed"
    elif cmp -s "$1" "$1.orig"; then
        ok
    else
        fail "$2: pre-existing $1 was changed (now starts: $(head -c 120 "$1"))"
    fi
}

# csv_steps FILE: the step column of each frame (one line per frame, in order).
csv_steps() {
    awk -F, 'NR > 1 && (NR == 2 || $1 != last) { print $1; last = $1 }' "$1"
}

# csv_steps_line FILE: the same, as one space-separated line.
csv_steps_line() {
    csv_steps "$1" | tr '\n' ' ' | sed 's/ $//'
}

# csv_field FILE STEP I COLUMN: a field of the trajectory row (step, particle i).
csv_field() {
    awk -F, -v s="$2" -v i="$3" -v c="$4" 'NR > 1 && $1 == s && $3 == i { print $c; exit }' "$1"
}

# energy_field FILE STEP COLUMN: a field of the energy row for step.
energy_field() {
    awk -F, -v s="$2" -v c="$3" 'NR > 1 && $1 == s { print $c; exit }' "$1"
}

# trajectory_ok FILE N DIM: FILE is a complete trajectory CSV for N particles
# in DIM dimensions: the right header, whole frames (rows i = 0..N-1 with one
# step and one t each), strictly increasing steps, every number printed as
# %.17g prints it and finite. Prints what is wrong and returns 1 otherwise.
trajectory_ok() {
    local f=$1 n=$2 dim=$3 header
    if [ "$dim" -eq 2 ]; then header='step,t,i,x,y,vx,vy'; else header='step,t,i,x,y,z,vx,vy,vz'; fi
    if [ ! -f "$f" ]; then
        echo "$f does not exist"
        return 1
    fi
    if [ "$(head -n 1 "$f")" != "$header" ]; then
        echo "$f: header is \"$(head -n 1 "$f")\", expected \"$header\""
        return 1
    fi
    awk -F, -v n="$n" -v nf="$(((dim == 2) ? 7 : 9))" -v f="$f" '
        NR == 1 { next }
        {
            row = NR - 2; i = row % n
            if (NF != nf) { printf "%s line %d: %d fields, expected %d\n", f, NR, NF, nf; bad = 1; exit }
            if ($3 != i) { printf "%s line %d: particle %s, expected %d (incomplete frame?)\n", f, NR, $3, i; bad = 1; exit }
            if (i == 0) {
                if (row > 0 && !($1 + 0 > step + 0)) { printf "%s line %d: step %s after %s\n", f, NR, $1, step; bad = 1; exit }
                step = $1; t = $2
            } else if ($1 != step || $2 != t) {
                printf "%s line %d: step/t %s,%s inside the frame of %s,%s\n", f, NR, $1, $2, step, t; bad = 1; exit
            }
            for (k = 1; k <= NF; k++) {
                if ($k !~ /^-?[0-9]/ || $k ~ /(inf|nan)/) { printf "%s line %d: field %d is not finite (%s)\n", f, NR, k, $k; bad = 1; exit }
                if ($k != "-0" && sprintf("%.17g", $k + 0) != $k) { printf "%s line %d: field %d (%s) is not printed as %%.17g\n", f, NR, k, $k; bad = 1; exit }
            }
        }
        END {
            if (bad) exit 1
            if (NR < 2) { printf "%s: no frames\n", f; exit 1 }
            if ((NR - 1) % n != 0) { printf "%s: %d rows, not whole frames of %d particles\n", f, NR - 1, n; exit 1 }
        }' "$f"
}

# energy_ok FILE: header step,t,kinetic,potential,total (extra columns
# allowed), numbers printed as %.17g (finite or not is not checked here).
energy_ok() {
    local f=$1
    if [ ! -f "$f" ]; then
        echo "$f does not exist"
        return 1
    fi
    case "$(head -n 1 "$f")" in
    step,t,kinetic,potential,total | step,t,kinetic,potential,total,*) ;;
    *)
        echo "$f: header is \"$(head -n 1 "$f")\", expected step,t,kinetic,potential,total"
        return 1
        ;;
    esac
    awk -F, -v f="$f" '
        NR == 1 { next }
        NF < 5 { printf "%s line %d: %d fields\n", f, NR, NF; bad = 1; exit }
        { for (k = 1; k <= 5; k++) if ($k !~ /(inf|nan)/ && $k != "-0" && sprintf("%.17g", $k + 0) != $k) { printf "%s line %d: field %d (%s) is not printed as %%.17g\n", f, NR, k, $k; bad = 1; exit } }
        END { if (bad) exit 1; if (NR < 2) { printf "%s: no rows\n", f; exit 1 } }' "$f"
}

# expect_trajectory FILE N DIM LABEL / expect_energy FILE LABEL
expect_trajectory() {
    local msg
    if msg=$(trajectory_ok "$1" "$2" "$3"); then ok; else fail "$4: $msg"; fi
}
expect_energy() {
    local msg
    if msg=$(energy_ok "$1"); then ok; else fail "$2: $msg"; fi
}

# near A B TOL: |A - B| <= TOL·max(1, |B|) (numbers as text).
near() {
    awk -v a="$1" -v b="$2" -v tol="$3" 'BEGIN {
        d = a - b; if (d < 0) d = -d
        m = b; if (m < 0) m = -m; if (m < 1) m = 1
        exit !(d <= tol * m) }'
}

# expect_near GOT EXPECTED TOL LABEL
expect_near() {
    if [ -n "$1" ] && near "$1" "$2" "$3"; then
        ok
    else
        fail "$4: got \"$1\", expected $2 (relative tolerance $3)"
    fi
}
