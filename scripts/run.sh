#!/usr/bin/env bash
# The main job: the editor on the built-in demo scene. With a display it opens
# the window; without one (a CI box, ssh) it runs under a virtual display,
# renders 60 frames and writes the whole window, panels included, to
# out/editor.png. Extra arguments go to the editor (a glTF path,
# --settings FILE.ron, --screenshot PATH --frames N, --autosave FILE.ron).
# The lab's side-by-side of every method against ground truth:
#   cargo run --release -p shadow_fins_lab -- image --scene demo --out out/demo.png
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
target="${CARGO_TARGET_DIR:-target}"
editor="$target/debug/shadow-fins-editor"
# The editor binary is one of the test suite's targets: build exactly what
# scripts/test.sh builds, so after the tests this takes seconds and the editor
# starts at once. (A plain `cargo run --example editor` resolves Bevy's
# features for the root package alone and rebuilt Bevy: 14 minutes.)
quiet=(--quiet)
if [ ! -x "$editor" ]; then
  echo "run: first build on this machine: the editor with the test suite's build (~25 min on 2 cores, once)…"
  quiet=()
fi
cargo test --workspace --locked --all-targets --no-run ${quiet[@]+"${quiet[@]}"}
echo "run: starting the editor ($editor)"
if [ -n "${DISPLAY:-}" ]; then
  exec "$editor" "$@"
else
  xvfb-run -a -s "-screen 0 1280x800x24" "$editor" --screenshot out/editor.png --frames 60 "$@"
  echo "no display: the editor ran on a virtual one; open out/editor.png"
fi
