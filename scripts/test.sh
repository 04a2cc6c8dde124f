#!/usr/bin/env bash
# The test command: bootstraps the environment, then runs the whole suite (DDS isolated per run).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$ROOT/scripts/bootstrap.sh"
cd "$ROOT"
exec python -m pytest "$@"
