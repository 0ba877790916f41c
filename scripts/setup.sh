#!/usr/bin/env bash
# Installs what building and testing need on a fresh Debian machine, and only
# what is missing. Safe to run again.
set -euo pipefail

missing=()
need_pkg() { dpkg -s "$1" >/dev/null 2>&1 || missing+=("$1"); }

# A C toolchain for crates with build scripts; pkg-config for -sys crates.
need_pkg build-essential
need_pkg pkg-config
# Headless rendering on the CPU (Mesa's lavapipe Vulkan driver) for the plugin's
# tests and examples; a real GPU's driver is used instead where there is one.
need_pkg libvulkan1
need_pkg mesa-vulkan-drivers
# The editor's window (winit loads the X11 libraries at run time) and a virtual
# display for machines without one (tests and the headless main job).
need_pkg libx11-6
need_pkg libxcursor1
need_pkg libxrandr2
need_pkg libxi6
need_pkg libxkbcommon-x11-0
need_pkg xvfb
need_pkg xauth
# The import-circle check of the test suite (scripts/module_cycles.py).
need_pkg python3

if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  sudo_cmd=""
  [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
  $sudo_cmd apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

if ! command -v cargo >/dev/null 2>&1; then
  echo "setup: cargo not found. Install Rust 1.95 (rustup) and run again." >&2
  exit 1
fi
