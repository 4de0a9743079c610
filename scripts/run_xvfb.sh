#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Runs a command under a private Xvfb (for trying the SDL2 pattern window without a monitor):
#   scripts/run_xvfb.sh [--size 1920x1080] -- <command> [args...]
# Xvfb picks a free display number itself (-displayfd), so several runs can coexist; DISPLAY is
# set for the command and the server is stopped when it exits. The framebuffer can be inspected
# meanwhile with `xwd -root -display $DISPLAY -out shot.xwd`.
set -euo pipefail
size=1920x1080
while [ $# -gt 0 ]; do
  case "$1" in
    --size) size="$2"; shift 2 ;;
    --) shift; break ;;
    *) break ;;
  esac
done
if [ $# -eq 0 ]; then
  echo "usage: $0 [--size WxH] -- command [args...]" >&2
  exit 2
fi
command -v Xvfb >/dev/null || { echo "run_xvfb.sh: Xvfb not found (apt-get install xvfb)" >&2; exit 1; }
fifo=$(mktemp -u /tmp/thinslab_xvfb_XXXXXX)
mkfifo "$fifo"
exec 3<>"$fifo"
rm -f "$fifo"
Xvfb -displayfd 3 -screen 0 "${size}x24" -nolisten tcp -noreset >/dev/null 2>&1 &
xvfb_pid=$!
trap 'kill "$xvfb_pid" 2>/dev/null; wait "$xvfb_pid" 2>/dev/null || true' EXIT
if ! read -r -t 10 number <&3; then
  echo "run_xvfb.sh: Xvfb did not start within 10 s" >&2
  exit 1
fi
export DISPLAY=":$number"
echo "run_xvfb.sh: Xvfb on $DISPLAY (${size})" >&2
"$@"
