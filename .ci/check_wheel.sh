#!/usr/bin/env bash
# Wheel check: build the sdist and the wheel from a copy of the checkout, install the wheel alone
# into a fresh virtual environment outside the checkout, and use it from another directory:
# every module and data file installed, every env id made with a localizer, reset and stepped,
# the shipped models found, the command line working (.ci/check_wheel.py does the Python part).
# Usage: .ci/check_wheel.sh   (PYTHON: the interpreter for the fresh venv; BUILD_PYTHON: one with
# the `build` package, default .venv/bin/python as `make test` leaves it)
set -euo pipefail
cd "$(dirname "$0")/.."
CHECKOUT=$(pwd -P)
PYTHON=${PYTHON:-python3}
BUILD_PYTHON=${BUILD_PYTHON:-$CHECKOUT/.venv/bin/python}
export SDL_VIDEODRIVER=dummy SDL_AUDIODRIVER=dummy MPLBACKEND=Agg PIP_DISABLE_PIP_VERSION_CHECK=1

TMP=$(mktemp -d "${TMPDIR:-/tmp}/crowdloc-wheel.XXXXXX")
trap 'rm -rf "$TMP"' EXIT
step() { echo "check_wheel: $*"; }
die() {
    echo "check_wheel: FAIL: $*" >&2
    exit 1
}
START=$SECONDS

step "building the sdist and the wheel from a copy of the working tree"
mkdir "$TMP/src" "$TMP/dist" "$TMP/run"
# tracked and untracked-but-not-ignored files: what a clean clone (plus new files) holds,
# without build/ or *.egg-info leftovers that could hide a file missing from the package data
git ls-files -z --cached --others --exclude-standard | tar -c --null --ignore-failed-read -T - -f - | tar -x -C "$TMP/src" -f -
"$BUILD_PYTHON" -m build --outdir "$TMP/dist" "$TMP/src" >"$TMP/build.log" 2>&1 ||
    { cat "$TMP/build.log" >&2; die "python -m build failed (log above)"; }
WHEELS=("$TMP"/dist/*.whl)
[[ ${#WHEELS[@]} -eq 1 && -f ${WHEELS[0]} ]] || die "expected one wheel in $TMP/dist, found: ${WHEELS[*]}"
WHEEL=${WHEELS[0]}
step "built $(basename "$WHEEL") ($((SECONDS - START)) s)"

step "installing torch, then the wheel, into a fresh venv"
"$PYTHON" -m venv "$TMP/venv"
VPY=$TMP/venv/bin/python
"$VPY" -m pip install --quiet -c constraints.txt torch==2.13.0 || die "installing torch into the fresh venv failed"
"$VPY" -m pip install --quiet -c constraints.txt "$WHEEL" || die "installing the wheel into the fresh venv failed"
"$VPY" -m pip check || die "pip check found broken requirements"
step "installed ($((SECONDS - START)) s)"

# from a directory outside the checkout; -I: no script dir, cwd or PYTHONPATH on sys.path
cd "$TMP/run"
export CROWDLOC_CACHE="$TMP/cache" NUMBA_CACHE_DIR="$TMP/numba"
"$VPY" -I "$CHECKOUT/.ci/check_wheel.py" "$CHECKOUT" || die "the installed package failed (message above)"
"$TMP/venv/bin/crowdloc" worlds >"$TMP/worlds.txt" || die "crowdloc worlds failed"
cat "$TMP/worlds.txt"
for env_id in $("$VPY" -I -c 'import envs; print(*envs.ENV_WORLDS)'); do
    grep -q "^$env_id " "$TMP/worlds.txt" || die "crowdloc worlds does not list $env_id"
done
"$TMP/venv/bin/crowdloc" eval --help >/dev/null || die "crowdloc eval --help failed"
step "crowdloc worlds and crowdloc eval --help work"
step "OK ($((SECONDS - START)) s)"
