#!/usr/bin/env bash
# Runs the documentation: every shell block of README.md and docs/guide/*.md, in order, and
# checks every relative link and image path of README.md, CONTRIBUTING.md and docs/**/*.md.
#
#   docs/check-docs.sh [PAGE.md …]        (default: README.md, then docs/guide/ in name order)
#
# A block is a fenced block whose info string is `sh` (or `bash`); `sh no-run: REASON` marks one
# that is not run (REASON is required). Python blocks are never run here and must each be marked
# `python no-run: REASON` (the package's own tests, python/tests/, run those calls). The blocks of one page run in order in one bash session
# (`set -euo pipefail`) in a scratch folder of their own, where `scenes/`, `examples/` and
# `python/` are links to the repository's, so the commands read as if run from the repository
# root and their outputs go to the scratch folder. After a page has run, every `out/…` path
# the page names in inline code must exist there.
#
# Inside the blocks `spibench` is the built binary (SPIBENCH_BIN, default target/debug/spibench;
# nothing is built here) and `cargo run [--release] [--quiet] -- ARGS` is `spibench ARGS`;
# `cargo test`, `cargo build` and `cargo install` are not run (CI runs the tests as a stage of
# their own, and the binary is already built). `python3` is SPIBENCH_DOCS_PYTHON (default: the
# CI's venv target/ci-python/venv/bin/python when it exists, else python3), which needs numpy.
#
# SPIBENCH_DOCS_QUICK=1 (what CI sets) runs the same commands at small sizes: `run`, `trace`,
# `sweep`, `tolerance` and `align` get `--rays SPIBENCH_DOCS_RAYS` (default 8192; an existing
# `--rays` value is replaced, and `--max-rays`, `--start-rays` are lowered to it),
# `--trials` at most 4 (unless `--trial K` names one trial of the full count), `--repeats` at most 2. The text shows the real command; its numbers
# are those of the real sizes. SPIBENCH_DOCS_KEEP=DIR keeps the scratch folders in DIR.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
# A relative SPIBENCH_BIN or SPIBENCH_DOCS_PYTHON names a file from where the script was started;
# the blocks run in scratch folders, so make them absolute first.
absolute() { case $1 in /* | "") printf '%s' "$1" ;; */*) printf '%s/%s' "$PWD" "$1" ;; *) printf '%s' "$1" ;; esac; }
SPIBENCH_BIN=$(absolute "${SPIBENCH_BIN:-}")
SPIBENCH_DOCS_PYTHON=$(absolute "${SPIBENCH_DOCS_PYTHON:-}")
cd "$repo"
bin=${SPIBENCH_BIN:-$repo/target/debug/spibench}
if [ ! -x "$bin" ]; then
    echo "check-docs: $bin is not built (run cargo build, or set SPIBENCH_BIN)" >&2
    exit 1
fi
py=${SPIBENCH_DOCS_PYTHON:-}
if [ -z "$py" ]; then
    if [ -x "$repo/target/ci-python/venv/bin/python" ]; then
        py=$repo/target/ci-python/venv/bin/python
    else
        # An absolute path: the blocks' `python3` is a function that calls "$__py", so a bare
        # name would call the function itself.
        py=$(command -v python3 || true)
        [ -n "$py" ] || { echo "check-docs: no python3 (set SPIBENCH_DOCS_PYTHON)" >&2; exit 1; }
    fi
fi
if [ "$#" -gt 0 ]; then
    pages=("$@")
else
    pages=(README.md)
    for page in docs/guide/*.md; do pages+=("$page"); done
fi
if [ -n "${SPIBENCH_DOCS_KEEP:-}" ]; then
    mkdir -p "$SPIBENCH_DOCS_KEEP"
    scratch=$(cd "$SPIBENCH_DOCS_KEEP" && pwd)
else
    scratch=$(mktemp -d "${TMPDIR:-/tmp}/spibench-docs.XXXXXX")
    trap 'rm -rf "$scratch"' EXIT
fi
start=$(date +%s)

status=0
# Relative links and images: [text](target), ![alt](target) and <img src="target">.
python3 - "$repo" <<'LINKS' || status=1
import pathlib, re, sys
repo = pathlib.Path(sys.argv[1])
files = [repo / "README.md", repo / "CONTRIBUTING.md"] + sorted((repo / "docs").rglob("*.md"))
link = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)|<img[^>]*\ssrc=\"([^\"]+)\"")
bad = []
for f in files:
    if not f.exists():
        continue
    fence = False
    for n, line in enumerate(f.read_text().splitlines(), 1):
        if line.lstrip().startswith("```"):
            fence = not fence
            continue
        # Code is not a link: fenced and indented blocks, inline code spans.
        if fence or line.startswith(("    ", "\t")):
            continue
        for m in link.finditer(re.sub(r"`[^`]*`", "", line)):
            target = m.group(1) or m.group(2)
            if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
                continue
            path = target.split("#", 1)[0]
            if not (f.parent / path).exists():
                bad.append(f"{f.relative_to(repo)}:{n}: {target} does not exist")
for b in bad:
    print(b, file=sys.stderr)
sys.exit(1 if bad else 0)
LINKS

# Turns a page into a bash script of its runnable blocks, and lists the out/ paths it names.
extract() {
    python3 - "$1" "$2" "$3" <<'EXTRACT'
import re, sys
page, script, named = sys.argv[1:4]
lines = open(page).read().splitlines()
out, paths, fence, block, start = [], set(), None, [], 0
for n, line in enumerate(lines, 1):
    if fence is None:
        m = re.match(r"^(\s*)```\s*(\S*)\s*(.*)$", line)
        if m:
            fence, block, start = (m.group(2), m.group(3)), [], n
            continue
        for code in re.findall(r"`([^`]+)`", line):
            for p in re.findall(r"(?:^|\s)(out/[A-Za-z0-9_./-]+)", code):
                paths.add(p)
    elif line.strip().startswith("```"):
        lang, rest = fence
        fence = None
        # Python blocks are not run here (they need the built package, some torch): each says
        # why, so that a new one is a decision, not an oversight.
        if lang == "python" and not re.match(r"no-run:\s*\S", rest):
            sys.exit(f"{page}:{start}: a python block is not run by this check; mark it "
                     "```python no-run: REASON")
        if lang not in ("sh", "bash"):
            continue
        if rest.startswith("no-run"):
            if not re.match(r"no-run:\s*\S", rest):
                sys.exit(f"{page}:{start}: a no-run block needs a reason (```sh no-run: REASON)")
            continue
        out.append(f"__block {page} {start}")
        out.extend(block)
    else:
        block.append(line)
if fence is not None:
    sys.exit(f"{page}:{start}: unclosed code block")
open(script, "w").write("\n".join(out) + "\n")
open(named, "w").write("\n".join(sorted(paths)) + ("\n" if paths else ""))
EXTRACT
}

# What every page's session starts with: the commands' stand-ins.
prelude() {
    cat <<PRELUDE
set -euo pipefail
__bin='$bin'
__py='$py'
__quick='${SPIBENCH_DOCS_QUICK:-}'
__rays='${SPIBENCH_DOCS_RAYS:-8192}'
PRELUDE
    cat <<'PRELUDE'
__where=start
__block() { __where="$1:$2"; echo "-- $1:$2" >&2; }
trap 's=$?; [ $s = 0 ] || echo "check-docs: the block at $__where failed (exit $s)" >&2' EXIT
spibench() {
    local args=() a sub="${1:-}" rays_seen=""
    if [ -n "$__quick" ]; then
        case "$sub" in
        run | trace | sweep | tolerance | align)
            # `--trial K` names a trial of the full count: keep that count.
            local keep_trials=""
            case " $* " in *" --trial "*) keep_trials=1 ;; esac
            while [ "$#" -gt 0 ]; do
                a=$1; shift
                case "$a" in
                --rays | --max-rays | --start-rays)
                    [ "$a" = --rays ] && rays_seen=1
                    args+=("$a" "$__rays"); shift ;;
                --trials)
                    if [ -n "$keep_trials" ]; then args+=("$a" "$1"); else args+=("$a" "$(( $1 < 4 ? $1 : 4 ))"); fi
                    shift ;;
                --repeats) args+=("$a" "$(( $1 < 2 ? $1 : 2 ))"); shift ;;
                *) args+=("$a") ;;
                esac
            done
            # --merge reads shard folders and traces nothing.
            case " ${args[*]} " in *" --merge "*) rays_seen=1 ;; esac
            [ -n "$rays_seen" ] || args+=(--rays "$__rays")
            set -- "${args[@]}" ;;
        esac
    fi
    "$__bin" "$@"
}
cargo() {
    case "${1:-}" in
    run)
        shift
        while [ "$#" -gt 0 ] && [ "$1" != -- ]; do shift; done
        [ "$#" -gt 0 ] && shift
        spibench "$@" ;;
    test | build | install) echo "(check-docs: cargo $1 is not run here)" >&2 ;;
    *) echo "check-docs: cargo $1 is not supported in a doc block" >&2; return 1 ;;
    esac
}
python3() { "$__py" "$@"; }
export -f spibench python3
PRELUDE
}

for page in "${pages[@]}"; do
    name=$(basename "$page" .md)
    [ "$page" = README.md ] && name=README
    dir=$scratch/$(dirname "$page" | tr / _)_$name
    rm -rf "$dir" && mkdir -p "$dir"
    ln -s "$repo/scenes" "$dir/scenes"
    ln -s "$repo/examples" "$dir/examples"
    ln -s "$repo/python" "$dir/python"
    extract "$page" "$dir/.blocks.sh" "$dir/.named.txt"
    { prelude; cat "$dir/.blocks.sh"; } > "$dir/.session.sh"
    page_start=$(date +%s)
    echo "== $page" >&2
    if ! (cd "$dir" && bash .session.sh) > "$dir/.stdout.txt" 2> "$dir/.stderr.txt"; then
        tail -n 30 "$dir/.stderr.txt" >&2
        status=1
        continue
    fi
    while read -r path; do
        [ -n "$path" ] || continue
        if [ ! -e "$dir/$path" ]; then
            echo "check-docs: $page names \`$path\`, which its blocks did not write" >&2
            status=1
        fi
    done < "$dir/.named.txt"
    echo "   $page: $(grep -c '^__block' "$dir/.blocks.sh" || true) blocks, $(( $(date +%s) - page_start )) s" >&2
done
echo "check-docs: $([ $status = 0 ] && echo passed || echo FAILED) in $(( $(date +%s) - start )) s" >&2
exit $status
