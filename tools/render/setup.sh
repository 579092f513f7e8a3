#!/usr/bin/env bash
# Create the virtual environment for the independent Mitsuba 3 plate renderer.
#
#   bash tools/render/setup.sh            # creates <repo>/.venv-render
#   VENV=/some/where bash tools/render/setup.sh
#
# Installs pinned mitsuba/drjit/numpy/pillow/tifffile from PyPI and, for the fast LLVM
# variants, Debian's libllvm19 (Dr.Jit 1.5 miscompiles with the LLVM 14/15 that Debian
# bookworm ships by default: "LLVM ERROR: Cannot select ... fmaximum"). Without a
# usable libLLVM the renderer falls back to the scalar_spectral_polarized variant.
# Finishes with a smoke test (Brewster-angle render, see render_plates.py verify).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
venv="${VENV:-$repo/.venv-render}"
python="${PYTHON:-python3}"

if [ ! -x "$venv/bin/python" ]; then
    "$python" -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --disable-pip-version-check -r "$here/requirements.txt"

# libLLVM >= 16 for the llvm_ad_* variants (optional).
if ! ls /usr/lib/x86_64-linux-gnu/libLLVM.so.19* >/dev/null 2>&1 \
    && ! ls /usr/lib/*/libLLVM-1[6-9]*.so* /usr/lib/*/libLLVM.so.2* >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        echo "installing libllvm19 (Debian) for Mitsuba's LLVM variants"
        apt-get update -qq >/dev/null || true
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19 >/dev/null \
            || echo "libllvm19 not installed: the scalar_spectral_polarized variant will be used"
    else
        echo "no libLLVM >= 16 found: the scalar_spectral_polarized variant will be used"
    fi
fi

"$venv/bin/python" "$here/render_plates.py" smoke
echo "render venv ready: $venv"
