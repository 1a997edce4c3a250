#!/usr/bin/env bash
# The Python package's API reference: pdoc renders the installed `spibench` package (its
# docstrings, the extension's docstrings from the binding's `///` comments, and the signatures
# of python/spibench/_spibench.pyi) to HTML, and fails on any warning pdoc prints.
#
#   python/docs.sh [PYTHON] [OUT]     (defaults: python3, target/python-docs)
#
# PYTHON must have the package (pip install ./python) and pdoc (pip install pdoc) installed.
# CI runs it in its Python stage; open OUT/spibench.html.
set -euo pipefail
py=${1:-python3}
out=${2:-target/python-docs}
# The torch operator and the deepinv adapter need torch and deepinv; without them they are left
# out (and said so).
modules=(spibench)
if "$py" -c "import torch, deepinv" >/dev/null 2>&1; then
    modules+=(spibench.nn spibench.deepinv spibench.noise)
else
    modules+=('!spibench.nn' '!spibench.deepinv' '!spibench.noise')
    echo "python/docs.sh: torch or deepinv is not installed: spibench.nn, spibench.deepinv and spibench.noise" \
        "are left out" >&2
fi
rm -rf "$out"
log=$(mktemp)
trap 'rm -f "$log"' EXIT
# pdoc reports problems (an unresolvable annotation, a broken link target, a module that fails
# to import) as Python warnings on stderr; any of them fails the build.
# torch's import runs `uname -p` (platform.processor), which pdoc would refuse with a warning.
if ! PDOC_ALLOW_EXEC=1 "$py" -W always -m pdoc --docformat restructuredtext --no-show-source -o "$out" \
    "${modules[@]}" 2> "$log"; then
    cat "$log" >&2
    echo "python/docs.sh: pdoc failed" >&2
    exit 1
fi
if grep -q . "$log"; then
    cat "$log" >&2
    echo "python/docs.sh: pdoc printed the warnings above" >&2
    exit 1
fi
test -s "$out/spibench.html"
echo "python/docs.sh: wrote $out/spibench.html"
