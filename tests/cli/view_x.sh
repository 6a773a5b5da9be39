# Shared by the viewer tests (view.sh, view_screenshot.sh): start a private
# Xvfb server on a free display (Xvfb -displayfd picks it) and stop it on
# exit. Sourced after lib.sh; sets DISPLAY. Exits 77 (CTest SKIP_RETURN_CODE,
# see tests/view.cmake) with the reason when no X server can be started.

# wait_for SECONDS COMMAND...: poll the command every 0.1 s until it succeeds;
# status 1 if it never did.
wait_for() {
    local limit=$1 start=$SECONDS
    shift
    while ! "$@"; do
        if [ $((SECONDS - start)) -ge "$limit" ]; then
            return 1
        fi
        sleep 0.1
    done
    return 0
}

if ! command -v Xvfb >/dev/null 2>&1; then
    echo "$TEST_NAME: SKIPPED: no X server can be started (Xvfb is not installed: apt-get install xvfb xauth)"
    exit 77
fi
# A held key repeats after 100 ms and then only every 30 s: a key held for
# 0.1-30 s (view.sh holds G for 0.6 s) repeats exactly once, so a viewer
# that acted on repeats fails the same way in every run. A quick tap may
# also repeat once on a loaded machine: N, [ and ] act on repeats, so a
# test that taps them must allow for it.
XVFB_PID=
stop_xvfb() {
    if [ -n "$XVFB_PID" ]; then
        kill "$XVFB_PID" 2>/dev/null
        wait "$XVFB_PID" 2>/dev/null
    fi
    rm -rf "$WORK"
}
trap stop_xvfb EXIT
: >"$WORK/xvfb.display"
Xvfb -displayfd 5 -screen 0 1280x1024x24 -nolisten tcp -noreset -ardelay 100 -arinterval 30000 5>"$WORK/xvfb.display" 2>"$WORK/xvfb.log" &
XVFB_PID=$!
xvfb_ready() { [ -s "$WORK/xvfb.display" ] || ! kill -0 "$XVFB_PID" 2>/dev/null; }
wait_for 30 xvfb_ready
DISPLAY_NUM=$(tr -dc '0-9' <"$WORK/xvfb.display")
if [ -z "$DISPLAY_NUM" ] || ! kill -0 "$XVFB_PID" 2>/dev/null; then
    echo "$TEST_NAME: SKIPPED: no X server can be started (Xvfb failed: $(head -c 400 "$WORK/xvfb.log"))"
    exit 77
fi
export DISPLAY=":$DISPLAY_NUM"
# Mesa and dbus leak at exit: no leak reports for the GL program under ASan.
export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0"
