#!/usr/bin/env bash
# Installs every build and test dependency of octshape from Debian 12 packages.
# Idempotent; needs root (or sudo). Nothing is downloaded from anywhere but Debian.
set -euo pipefail
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
PKGS=(
  build-essential cmake ninja-build pkg-config git
  clang libclang-rt-14-dev            # libFuzzer + sanitizer runtimes for the fuzz target
  libeigen3-dev
  libvtk9-dev
  libopencv-dev
  libtiff-dev zlib1g-dev              # the Heyex XML export's TIFF B-scans; PNG QC pictures
  libopenjp2-7-dev                    # the Topcon .fda's JPEG 2000 B-scans
  libssl-dev                          # libcrypto: SHA-256 (CPU SHA extensions), HMAC
  libcli11-dev nlohmann-json3-dev libspdlog-dev libfmt-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  snakemake                           # workflow/Snakefile (cohort scale-out) and its test
  slurmctld slurmd slurm-client munge # the workflow's test on a real Slurm (tests/workflow/)
  r-base-core r-cran-geepack r-cran-psych r-cran-lme4   # the R recipe docs/r/ and its test
  chromium                            # the QC gallery test (headless)
)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
echo "octshape: all dependencies installed"
