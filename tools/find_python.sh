#!/bin/sh
# Prints the command of a Python >= 3.11 to build the virtual environment with.
#   tools/find_python.sh [PYTHON]
# With an argument (the Makefile's PYTHON), that interpreter only: a name on PATH or a path.
# Without, the first of python3.13, python3.12, python3.11, python3 on PATH that is 3.11 or newer.
# Nothing found: one "error:" line on stderr, exit status 1. Only shell built-ins are used, so the
# choice depends on PATH alone (tests/test_install.py runs it against fake interpreters).
MIN_MAJOR=3
MIN_MINOR=11

version_of() {  # "MAJOR.MINOR" of interpreter $1, empty if it does not run
    "$1" -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null
}

recent_enough() {  # is "MAJOR.MINOR" $1 at least MIN_MAJOR.MIN_MINOR?
    major=${1%%.*}
    minor=${1#*.}
    case "$major$minor" in *[!0-9]*|"") return 1 ;; esac
    [ "$major" -gt "$MIN_MAJOR" ] || { [ "$major" -eq "$MIN_MAJOR" ] && [ "$minor" -ge "$MIN_MINOR" ]; }
}

if [ -n "$1" ]; then
    if ! command -v "$1" >/dev/null 2>&1; then
        echo "error: PYTHON=$1 not found (give a Python >= $MIN_MAJOR.$MIN_MINOR on PATH or its path)" >&2
        exit 1
    fi
    v=$(version_of "$1")
    if [ -z "$v" ]; then
        echo "error: PYTHON=$1 does not run (a pyenv shim of a version not selected?)" >&2
        exit 1
    fi
    if ! recent_enough "$v"; then
        echo "error: PYTHON=$1 is Python $v; $MIN_MAJOR.$MIN_MINOR or newer is required" >&2
        exit 1
    fi
    echo "$1"
    exit 0
fi

for c in python3.13 python3.12 python3.11 python3; do
    if command -v "$c" >/dev/null 2>&1 && recent_enough "$(version_of "$c")"; then
        echo "$c"
        exit 0
    fi
done
echo "error: no Python >= $MIN_MAJOR.$MIN_MINOR on PATH (tried python3.13, python3.12, python3.11, python3); name one with make PYTHON=/path/to/python3" >&2
exit 1
