#!/bin/bash
# The editor's on-screen pen latency (issue 12): a stroke over the 4K demo at 1:1 under Xvfb,
# timed by the editor itself (RGBN_EDITOR_TIMING=1). Needs xvfb, xdotool, and a release build
# with the gui feature (`cargo build --release`). The clicks assume the default window
# (1560×940) on a 1600×1000 screen: View → Actual pixels, then the Pen tool.
#
#   bash benches/editor_stroke.sh [BINARY] [LABEL]
#
# Prints the median / p90 / max of "tool edit → relit viewport" (the frame that puts the
# result on screen), the frame interval during the stroke, and when the worker had it ready.
set -u
BIN=${1:-target/release/rgbn}
LABEL=${2:-stroke}
WORK=$(mktemp -d)
ROOT=$(cd "$(dirname "$0")/.." && pwd)
sed 's/Int(512)/Int(4096)/' "$ROOT/graphs/demo.ron" > "$WORK/demo4k.ron"
export DISPLAY=${DISPLAY:-:99}
if ! xdotool getdisplaygeometry >/dev/null 2>&1; then
    Xvfb "$DISPLAY" -screen 0 1600x1000x24 >/dev/null 2>&1 &
    XVFB=$!
    sleep 1
fi
LOG="$WORK/$LABEL.err"
RGBN_EDITOR_TIMING=1 "$BIN" edit "$WORK/demo4k.ron" > /dev/null 2> "$LOG" &
EDITOR=$!
# The whole graph evaluated first.
for _ in $(seq 1 90); do grep -q "evaluation .* took" "$LOG" && break; sleep 1; done
sleep 1
xdotool mousemove 126 11 click 1; sleep 0.7; xdotool mousemove 170 381 click 1; sleep 2
xdotool mousemove 733 244 click 1; sleep 1
n0=$(wc -l < "$LOG")
xdotool mousemove 800 500 mousedown 1
for i in $(seq 1 80); do xdotool mousemove $((800 + i * 9 / 2)) $((500 + i)); sleep 0.016; done
xdotool mouseup 1
sleep 3
tail -n +$((n0 + 1)) "$LOG" > "$WORK/stroke.log"
grep "tool edit" "$WORK/stroke.log" | sed 's/.*after \([0-9]*\) ms (newest.*/\1/' | sort -n |
    awk -v l="$LABEL" '{a[NR]=$1} END{print l ": on screen n", NR, "median", a[int(NR/2)+1], "p90", a[int(NR*0.9)+1], "max", a[NR], "ms"}'
grep "gesture" "$WORK/stroke.log"
grep "ready" "$WORK/stroke.log" | sed 's/.*ready \([0-9.]*\) ms.*/\1/' | sort -n |
    awk '{a[NR]=$1} END{print "ready: median", a[int(NR/2)+1], "p90", a[int(NR*0.9)+1], "ms"}'
kill "$EDITOR" 2>/dev/null
[ -n "${XVFB:-}" ] && kill "$XVFB"
rm -rf "$WORK"
