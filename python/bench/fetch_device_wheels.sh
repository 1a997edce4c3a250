#!/usr/bin/env bash
# Fills target/device-wheels/ on a networked machine for python/device_check.sh (which installs
# from it with --no-index): the spibench wheel (built by maturin from this workspace), deepinv,
# and the dependencies deepinv imports that torch images often lack (pure Python, plus h5py for
# CPython 3.10–3.13 and pytest). About 26 MB.
set -euo pipefail
cd "$(dirname "$0")/../.."
W=target/device-wheels
mkdir -p "$W"
dl() { python3 -m pip download --quiet --disable-pip-version-check --no-deps --only-binary=:all: -d "$W" "$@"; }
dl deepinv tqdm natsort requests idna urllib3 certifi einops torchmetrics lightning-utilities \
    packaging typing_extensions charset-normalizer pytest iniconfig pluggy exceptiongroup tomli \
    pygments --platform any --python-version 3.10
for v in 3.10 3.11 3.12 3.13; do
    dl h5py --python-version "$v" --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64
done
python3 -m pip wheel --quiet --disable-pip-version-check --no-deps -w "$W" ./python
du -sh "$W"
