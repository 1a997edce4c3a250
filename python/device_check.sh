#!/usr/bin/env bash
# The device check of the Python package: the deepinv adapter's tests (which skip without
# torch) and the benchmarks of python/bench/bench_operator.py, on a Linux x86_64 machine with
# python3, torch, numpy and scipy, without network. Run from the repository root:
#
#     OUT=/some/folder bash python/device_check.sh
#
# Everything it installs comes from target/device-wheels/ (made on a networked machine; see
# python/bench/fetch_device_wheels.sh): the spibench wheel, deepinv, and those of deepinv's pure-Python
# dependencies (and h5py, pytest) that the machine lacks, installed with
# `pip --no-index --no-deps --target` into $OUT/site, which goes on PYTHONPATH. Results:
# $OUT/device_check.log, $OUT/pytest.txt, $OUT/bench.json, $OUT/bench_1thread.json.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-$PWD/target/device-out}
W="$PWD/target/device-wheels"
PY=${PYTHON:-python3}
mkdir -p "$OUT"
exec > >(tee "$OUT/device_check.log") 2>&1
site="$OUT/site"
rm -rf "$site" && mkdir -p "$site"
export PYTHONPATH="$site"
echo "== machine"
uname -a; nproc; "$PY" --version
"$PY" -c "import torch, numpy, scipy; print('torch', torch.__version__, 'numpy', numpy.__version__, 'scipy', scipy.__version__, 'cuda', torch.cuda.is_available())"
ls "$W"
inst() { "$PY" -m pip install --quiet --disable-pip-version-check --no-index --no-deps \
    --find-links "$W" --target "$site" "$@"; }
echo "== install"
inst spibench deepinv || { echo "cannot install spibench/deepinv from $W"; exit 1; }
for pair in tqdm:tqdm natsort:natsort requests:requests idna:idna urllib3:urllib3 \
    certifi:certifi charset_normalizer:charset-normalizer h5py:h5py einops:einops \
    packaging:packaging typing_extensions:typing-extensions \
    lightning_utilities:lightning-utilities torchmetrics:torchmetrics \
    pluggy:pluggy iniconfig:iniconfig pygments:pygments exceptiongroup:exceptiongroup \
    tomli:tomli pytest:pytest; do
    mod=${pair%%:*}; pkg=${pair##*:}
    if ! "$PY" -c "import $mod" >/dev/null 2>&1; then
        echo "installing $pkg"; inst "$pkg" || echo "could not install $pkg"
    fi
done
if ! "$PY" -c "import torchvision" >/dev/null 2>&1; then
    echo "torchvision is missing: using the placeholder of python/bench/torchvision_shim"
    export PYTHONPATH="$site:$PWD/python/bench/torchvision_shim"
fi
"$PY" -c "import deepinv, spibench; print('deepinv', deepinv.__version__, 'spibench', spibench.__version__, spibench.__file__)" \
    || echo "deepinv or spibench does not import: the deepinv tests will skip"
echo "== pytest"
# Run from the tests folder's parent with the installed package (not the source tree).
"$PY" -m pytest -v -rs -p no:cacheprovider python/tests 2>&1 | tee "$OUT/pytest.txt"
echo "== benchmarks"
timeout 300 "$PY" python/bench/bench_operator.py --out "$OUT/bench.json"
timeout 200 "$PY" python/bench/bench_operator.py --threads 1 --repeats 5 \
    --out "$OUT/bench_1thread.json"
echo "== done"
