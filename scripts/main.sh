#!/usr/bin/env bash
# The main job: bootstraps the environment, then runs the full pipeline on the default scenario.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$ROOT/scripts/bootstrap.sh"
cd "$ROOT"
exec saw-ros demo "$@"
