#!/usr/bin/env bash
# Prepare a GPU check on a lent machine that has no package index (the device tool's CUDA image: Python 3.12,
# torch with CUDA, onnxruntime, numpy, opencv, matplotlib, jinja2, rich, pytest(-xdist) already there).
# Downloads, into .whl/ (git-ignored), the Python 3.12 wheels of pilotlab's other dependencies, and builds
# pybullet for Python 3.12 (it publishes only a source archive for 3.2.7): ~6 minutes on 2 cores, the
# stripped module is 8 MB (the wheel with its debug symbols and pybullet_data is 100 MB, over what travels).
# Run from the repository root, once, here: `tools/gpu/prepare.sh [python3.12]`; then tools/gpu/check.sh there.
set -euo pipefail
mkdir -p .whl/pb
platforms=(--platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 --platform manylinux_2_24_x86_64
           --platform manylinux_2_28_x86_64 --platform manylinux_2_34_x86_64 --platform manylinux1_x86_64
           --platform manylinux_2_5_x86_64 --platform any)
# What the image lacks (versions as this checkout's venv had them, 2026-11-27); --no-deps: each is named.
for package in pydantic==2.14.4 pydantic_core==2.50.5 annotated-types==0.8.0 typing-inspection==0.4.5 \
        typing_extensions==4.15.0 rosbags==0.11.9 backports.zstd==1.8.0 apsw==3.54.1.0 lz4==4.4.5 \
        ruamel.yaml==0.19.1 zstandard==0.25.0 gymnasium==1.4.0 Farama-Notifications==0.0.6 torchao==0.18.0 \
        trimesh==5.2.0 pycollada==0.9.3 shapely==2.2.0 dask==2026.8.0 distributed==2026.8.0 partd==1.4.2 \
        locket==1.0.0 tblib==3.2.2 zict==3.0.0 tornado==6.6.1; do
    python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
        "${platforms[@]}" -d .whl "$package"
done
if [ ! -f .whl/pb/pybullet.cpython-312-x86_64-linux-gnu.so ]; then
    py312=${1:-$(command -v python3.12 || ls /root/.pyenv/versions/3.12*/bin/python3.12 2>/dev/null | head -1)}
    [ -n "$py312" ] || { echo "no Python 3.12 here to build pybullet with: name one (tools/gpu/prepare.sh PYTHON)"; exit 1; }
    build=$(mktemp -d)
    "$py312" -m venv "$build/venv" && "$build/venv/bin/pip" install -q setuptools wheel
    "$build/venv/bin/pip" wheel -q --no-deps --no-build-isolation pybullet==3.2.7 -w "$build/out"
    (cd "$build" && python3 -m zipfile -e out/pybullet-*.whl x)
    strip -o .whl/pb/pybullet.cpython-312-x86_64-linux-gnu.so "$build"/x/pybullet.cpython-312-x86_64-linux-gnu.so
    rm -rf "$build"
fi
du -sh .whl
echo "the tracked tree and .whl travel together (64 MiB at most): move docs/reports/ aside for the call if needed"
