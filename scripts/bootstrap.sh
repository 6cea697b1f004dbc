#!/usr/bin/env bash
# Set up clbeam on a fresh Debian machine and run one task.
#
#   bash scripts/bootstrap.sh demo     # set up, then `clbeam demo`
#   bash scripts/bootstrap.sh test     # set up, then the whole test suite
#   bash scripts/bootstrap.sh bench    # set up, then `clbeam bench`
#
# "Set up" = install an OpenCL CPU driver (Debian's PoCL) when no OpenCL
# platform is found, plus Oclgrind for the kernel memory checks; create the
# virtual environment .venv; install clbeam with its test extras.
set -euo pipefail
cd "$(dirname "$0")/.."
task="${1:-test}"; shift || true

need_apt=()
if ! { [ -d /etc/OpenCL/vendors ] && ls /etc/OpenCL/vendors/*.icd >/dev/null 2>&1; }; then
    need_apt+=(pocl-opencl-icd)
fi
if [ "$task" = test ] && ! command -v oclgrind >/dev/null 2>&1; then
    need_apt+=(oclgrind)
fi
if [ ${#need_apt[@]} -gt 0 ]; then
    if [ "$(id -u)" = 0 ]; then
        echo "clbeam setup: installing ${need_apt[*]} (Debian packages)"
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need_apt[@]}" >/dev/null
    else
        echo "clbeam setup: please install ${need_apt[*]} (sudo apt-get install ${need_apt[*]}); continuing" >&2
    fi
fi

PY="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
    echo "clbeam setup: creating .venv"
    "$PY" -m venv .venv
fi
stamp=.venv/.clbeam-installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
    echo "clbeam setup: installing clbeam and its test extras into .venv"
    .venv/bin/python -m pip install -q --upgrade pip
    .venv/bin/python -m pip install -q -e ".[test]"
    # arlpy, the peer library of tests/compare/test_arlpy.py, pins numpy<2 in its metadata
    # although its arlpy.uwa functions run on numpy 2: installed without its pins
    .venv/bin/python -m pip install -q --no-deps "arlpy==1.9.3"
    touch "$stamp"
fi
# bytecode written now (only what changed): where the environment stops Python writing it, every
# command would compile clbeam's modules again at start-up (about 0.1 s)
.venv/bin/python -m compileall -q clbeam >/dev/null

case "$task" in
    demo)  exec .venv/bin/clbeam demo "$@" ;;
    # one worker process per core, each test file on one worker (its module fixtures built once);
    # CLBEAM_TEST_WORKERS=0 runs the suite in this process
    test)  exec .venv/bin/python -m pytest -n "${CLBEAM_TEST_WORKERS:-auto}" --dist loadfile "$@" ;;
    bench) exec .venv/bin/clbeam bench "$@" ;;
    *)     exec .venv/bin/clbeam "$task" "$@" ;;
esac
