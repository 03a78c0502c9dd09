#!/usr/bin/env bash
# Screenshot of rviz (rviz/monitor.rviz) during a headless demo run, for the README.
#   scripts/rviz_screenshot.sh OUT.png [SECONDS_INTO_RUN]
# Needs xvfb and imagemagick (Debian). Run inside the workspace environment (./run shot does).
set -euo pipefail
out="$1"; wait_s="${2:-6}"
export DISPLAY=:97
Xvfb :97 -screen 0 1000x700x24 >/dev/null 2>&1 &
xvfb=$!
trap 'kill $launch $xvfb 2>/dev/null || true' EXIT
sleep 1
tmp="$(mktemp -d)"
roslaunch pmsm_param_id demo.launch rviz:=true duration:=20 bag:="$tmp/shot.bag" >"$tmp/launch.log" 2>&1 &
launch=$!
sleep "$wait_s"
import -window root "$out"
kill -INT $launch; wait $launch 2>/dev/null || true
echo "screenshot: $out"
