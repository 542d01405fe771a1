#!/bin/sh
# Build BLASFEO and HPIPM for this CPU (static, -fPIC) at the versions whose headers CasADi 3.7-3.8's
# generated code was written for, and install them into PREFIX; then
#   export PSDM_HPIPM_DIR=PREFIX
# makes trajopt.mpc_rti.compile_rti (and benchmarks/mpc.py) link them instead of CasADi's portable
# BLASFEO (TARGET_GENERIC). acados does the same for its HPIPM. `make hpipm` installs into psdm's cache
# folder (trajopt.hpipm_c.hpipm_cache_folder), where compile_rti finds them without PSDM_HPIPM_DIR.
#
# Usage: sh benchmarks/build_hpipm.sh PREFIX [BLASFEO_TARGET] [HPIPM_TARGET]
#   BLASFEO_TARGET: X64_INTEL_HASWELL (AVX2+FMA, default), X64_INTEL_SANDY_BRIDGE (AVX), GENERIC, ...
#   HPIPM_TARGET:   AVX (default) or GENERIC
set -e
PREFIX=${1:?usage: build_hpipm.sh PREFIX [BLASFEO_TARGET] [HPIPM_TARGET]}
BLASFEO_TARGET=${2:-X64_INTEL_HASWELL}
HPIPM_TARGET=${3:-AVX}
BLASFEO_VERSION=0.1.4.2
HPIPM_COMMIT=af3ca4757a80dc9658163caeac7dcc0a26f77be3
WORK=$(mktemp -d)
git clone -q "${BLASFEO_URL:-https://github.com/giaf/blasfeo}" "$WORK/blasfeo"
git -C "$WORK/blasfeo" checkout -q "$BLASFEO_VERSION"
git clone -q "${HPIPM_URL:-https://github.com/giaf/hpipm}" "$WORK/hpipm"
git -C "$WORK/hpipm" checkout -q "$HPIPM_COMMIT"
COMMON="-DBUILD_SHARED_LIBS=OFF -DCMAKE_POSITION_INDEPENDENT_CODE=ON -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX=$PREFIX"
cmake -S "$WORK/blasfeo" -B "$WORK/blasfeo/build" $COMMON -DTARGET="$BLASFEO_TARGET" -DBLASFEO_EXAMPLES=OFF
cmake --build "$WORK/blasfeo/build" -j2 --target install
cmake -S "$WORK/hpipm" -B "$WORK/hpipm/build" $COMMON -DTARGET="$HPIPM_TARGET" -DBLASFEO_PATH="$PREFIX" -DHPIPM_TESTING=OFF
cmake --build "$WORK/hpipm/build" -j2 --target install
rm -rf "$WORK"
echo "export PSDM_HPIPM_DIR=$PREFIX"
