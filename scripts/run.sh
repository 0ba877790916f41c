#!/usr/bin/env bash
# The main job: the editor on the built-in demo scene. With a display it opens
# the window; without one (a CI box, ssh) it runs under a virtual display,
# renders 60 frames and writes the whole window, panels included, to
# out/editor.png. Extra arguments go to the editor (a glTF path,
# --settings FILE.ron, --screenshot PATH --frames N).
# The lab's side-by-side of every method against ground truth:
#   cargo run --release -p shadow_fins_lab -- image --scene demo --out out/demo.png
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# The dev profile builds dependencies optimised (Cargo.toml) and shares the
# test suite's build; a release build of Bevy is another ~15 minutes.
if [ -n "${DISPLAY:-}" ]; then
  cargo run --locked --example editor -- "$@"
else
  xvfb-run -a -s "-screen 0 1280x800x24" \
    cargo run --locked --example editor -- --screenshot out/editor.png --frames 60 "$@"
  echo "no display: the editor ran on a virtual one; open out/editor.png"
fi
