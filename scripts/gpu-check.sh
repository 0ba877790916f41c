#!/usr/bin/env bash
# The GPU check: the render tests on a real GPU (the extraction race test among
# them) and the rendered lab's timing rows, written as one markdown report.
#
# A GPU machine lent through the `device` tool reaches no network, so it cannot
# fetch crates: the binaries are built here and carried there.
#
#   bash scripts/gpu-check.sh pack    # here: release binaries, stripped and
#                                     # zstd-packed into .gpu-check/ (ignored by git)
#   bash scripts/gpu-check.sh run     # there (or here, on lavapipe): unpack, run,
#                                     # write ${OUT:-out/gpu-check}/gpu-check.md
#
# With the device tool: pack first, then one call
#   run(command="bash scripts/gpu-check.sh run", carry=[".gpu-check", ".gl"], timeout_s=540)
# where .gl holds the Vulkan loader's .deb files (see the device tool's README;
# `pack` downloads them when apt can). The run takes 8 minutes at most (its
# steps' limits add up to 480 s): a step that runs out is reported, not fatal.
# Paste the report into BENCHMARKS.md with the GPU named.
set -uo pipefail
cd "$(dirname "$0")/.."
mode="${1:-run}"
pack_dir=.gpu-check
target="${CARGO_TARGET_DIR:-target}"
profile="${GPU_CHECK_PROFILE:-release}"

case "$mode" in
pack)
  set -e
  bash scripts/setup.sh
  command -v zstd >/dev/null || { sudo_cmd=""; [ "$(id -u)" -ne 0 ] && sudo_cmd=sudo; $sudo_cmd apt-get install -y -qq zstd; }
  grep -qx '/.gpu-check/' .git/info/exclude 2>/dev/null || echo '/.gpu-check/' >>.git/info/exclude
  grep -qx '/.gl/' .git/info/exclude 2>/dev/null || echo '/.gl/' >>.git/info/exclude
  flag=(); [ "$profile" = release ] && flag=(--release)
  echo "gpu-check: building the render tests and the render lab ($profile)…"
  cargo test --workspace --locked --all-targets ${flag[@]+"${flag[@]}"} --no-run
  dir="$target/$([ "$profile" = release ] && echo release || echo debug)"
  tests=$(ls -t "$dir"/deps/render-* | grep -v '\.d$' | head -1)
  rm -rf "$pack_dir" && mkdir -p "$pack_dir"
  for pair in "render-tests:$tests" "render-lab:$dir/shadow-fins-render-lab"; do
    name=${pair%%:*}; bin=${pair#*:}
    strip -o "$pack_dir/$name" "$bin"
    zstd -q -19 --rm "$pack_dir/$name"
  done
  if [ ! -d .gl ] && command -v apt-get >/dev/null; then
    o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64'
    mkdir -p .gl /tmp/amd64/partial
    # shellcheck disable=SC2086
    apt-get $o update -qq && (cd .gl && apt-get $o download libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2) || true
  fi
  du -sh "$pack_dir" .gl 2>/dev/null
  echo "gpu-check: packed; carry .gpu-check and .gl to the GPU machine and run: bash scripts/gpu-check.sh run"
  ;;
run)
  out="${OUT:-out/gpu-check}"
  mkdir -p "$out"
  report="$out/gpu-check.md"
  log="$out/gpu-check.log"
  : >"$log"
  # The Vulkan loader, where the machine lacks one.
  # (A process substitution: under pipefail, grep -q closing the pipe early
  # would read as "no loader" and unpack over a working one.)
  if ! grep -q libvulkan.so.1 < <(ldconfig -p 2>/dev/null) && ls .gl/*.deb >/dev/null 2>&1; then
    for f in .gl/*.deb; do dpkg -x "$f" /; done
    ldconfig
  fi
  if [ -f /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json ]; then
    export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
  fi
  bin=/tmp/gpu-check-bin
  mkdir -p "$bin"
  if ls "$pack_dir"/*.zst >/dev/null 2>&1; then
    for f in "$pack_dir"/*.zst; do zstd -q -d -f "$f" -o "$bin/$(basename "$f" .zst)"; done
  else
    echo "gpu-check: no packed binaries in $pack_dir; building here ($profile)…" | tee -a "$log"
    flag=(); [ "$profile" = release ] && flag=(--release)
    cargo test --workspace --locked --all-targets ${flag[@]+"${flag[@]}"} --no-run >>"$log" 2>&1 || exit 1
    dir="$target/$([ "$profile" = release ] && echo release || echo debug)"
    cp "$(ls -t "$dir"/deps/render-* | grep -v '\.d$' | head -1)" "$bin/render-tests"
    cp "$dir/shadow-fins-render-lab" "$bin/render-lab"
  fi
  chmod +x "$bin"/*
  # The binaries read assets and the fuzz corpus relative to the repository.
  export CARGO_MANIFEST_DIR="$PWD"
  step() { # step NAME SECONDS COMMAND…: runs, times, reports; never stops the script
    local name=$1 limit=$2; shift 2
    local start=$SECONDS
    echo "## $name" >>"$report"; echo >>"$report"
    echo "\`$*\`" | sed "s|$bin/||" >>"$report"; echo >>"$report"
    timeout "$limit" "$@" >"$out/step.out" 2>>"$log"
    local rc=$?
    cat "$out/step.out" >>"$report"; echo >>"$report"
    echo "_exit $rc after $((SECONDS - start)) s (limit $limit s)_" >>"$report"; echo >>"$report"
    echo "gpu-check: $name: exit $rc in $((SECONDS - start)) s"
  }
  {
    echo "# GPU check"
    echo
    echo "$(date -u +%Y-%m-%d), $(nproc) cores; GPU: $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null || echo 'see the adapter line in the log')"
    echo
  } >"$report"
  # Render tests on the GPU (the race test, oracle agreement, compositing…);
  # the editor tests start the editor binary built here and need a display:
  # they test the UI, not the GPU, and stay on the build machine.
  step "render tests" 200 "$bin/render-tests" --test-threads 2 --skip editor
  grep -m1 -i "AdapterInfo\|adapter" "$log" >>"$report" 2>/dev/null
  lab=("$bin/render-lab" measure --layers 16 --refinement on --falloff disk-segment --map-resolution 1024)
  step "static scene, 1k–1M triangles" 100 "${lab[@]}" --blob-triangles 1000,10000,100000,1000000 --no-truth \
    --methods fins,bevy-hard,bevy-pcss --frames 20 --warmup 3 --out "$out/static"
  step "light moving every frame, 1k–1M triangles" 100 "${lab[@]}" --blob-triangles 1000,10000,100000,1000000 \
    --no-truth --methods fins,bevy-hard,bevy-pcss --moving-light --frames 20 --warmup 3 --out "$out/moving"
  step "speed against accuracy (large-light, near-contact, kitbash, greeble-tower)" 80 "${lab[@]}" \
    --scenes large-light,near-contact,kitbash,greeble-tower --methods fins,coverage,outer-fins,bevy-hard,bevy-pcss \
    --frames 20 --warmup 3 --out "$out/accuracy"
  echo "gpu-check: report in $report"
  ;;
*)
  echo "usage: bash scripts/gpu-check.sh pack|run" >&2
  exit 2
  ;;
esac
