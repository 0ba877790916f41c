#!/usr/bin/env bash
# The main job: the lab renders the built-in demo scene by every method beside
# the 1024-sample ground truth, with error heat maps, and prints the error table.
# Extra arguments go to `shadow-fins-lab image` (try --scene ring-plate, or
# --gltf FILE --light-center x,y,z --radius R).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cargo run --release --locked -p shadow_fins_lab -- image --scene demo --width 320 --height 240 --out out/demo.png "$@"
echo "open out/demo.png"
