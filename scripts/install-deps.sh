#!/usr/bin/env bash
# Installs the Debian 12 packages cellray's build, tests and examples need,
# only those missing. Extra package names may be passed as arguments.
set -euo pipefail
pkgs=(cmake make g++ clang-14 binutils libxsimd-dev libtbb-dev libglm-dev libstb-dev catch2
      libbenchmark-dev libpugixml-dev zlib1g-dev libcli11-dev nlohmann-json3-dev fonts-dejavu-core
      libembree-dev
      # cellray-render's Exodus II reader (.ex2)
      libexodusii-dev
      # cellray-mpi-render and its tests: MPI + IceT 2.2 inside ParaView 5.11 (apt: ~2.5 min)
      libopenmpi-dev openmpi-bin paraview-dev "$@")
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo=sudo
  echo "installing: ${missing[*]}" >&2
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
