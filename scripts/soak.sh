#!/usr/bin/env bash
# Soak (outside the test suite): the main job's graph at real-time factor 0.5 for 30 minutes,
# every node's memory sampled each 10 s; passes when it stays flat within 5 % after the first
# minute and nothing is lost. Arguments go to scripts/soak.py (--minutes 3 for a short try;
# --help). Writes out/soak_<date-time>/: rss.csv, rss.png, result.json, the nodes' logs.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$ROOT/scripts/bootstrap.sh"
cd "$ROOT"
exec python "$ROOT/scripts/soak.py" "$@"
