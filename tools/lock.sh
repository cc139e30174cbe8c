#!/usr/bin/env bash
# Refresh the lock files from pyproject.toml: every dependency, direct and transitive, pinned with
# its hashes. requirements-test.lock holds the package with every extra (what CI tests);
# requirements.lock the package alone, at the same versions. setuptools, the build backend, is
# pinned too: the locked installs build warpsoft without fetching anything unpinned
# (pip install --no-build-isolation --no-deps -e .). Needs uv (pip install uv).
# Then run the README's test command on a fresh clone before committing the new locks.
set -euo pipefail
cd "$(dirname "$0")/.."
build=$(mktemp)
trap 'rm -f "$build"' EXIT
echo "setuptools>=68" > "$build"
common=(--universal --fork-strategy fewest --python-version 3.11 --generate-hashes --quiet --no-header)
uv pip compile pyproject.toml "$build" --extra test --extra sweep --extra plot --extra tools "${common[@]}" \
    -o requirements-test.lock "$@"
uv pip compile pyproject.toml "$build" -c requirements-test.lock "${common[@]}" -o requirements.lock
