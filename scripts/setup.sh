#!/usr/bin/env bash
# Set up rc1_drake from the repository's top folder: Graphviz (Debian's package, for drawing Diagrams in
# the notebooks), Chromium (Debian's, the animation's test opens it in a browser) and .venv with the pinned
# Python packages (requirements.lock).
set -euo pipefail
cd "$(dirname "$0")/.."
GRAPHVIZ=graphviz=2.42.2-7+deb12u1
CHROMIUM=chromium=156.0.8078.108-1~deb12u1  # the animation's test looks at it in a browser
if ! command -v dot >/dev/null 2>&1 || ! command -v chromium >/dev/null 2>&1; then
  if [ "$(id -u)" -eq 0 ]; then sudo=""; else sudo="sudo"; fi
  if command -v apt-get >/dev/null 2>&1; then
    $sudo apt-get update -qq
    # The pinned version where the archive still has it, else the archive's own (a security update).
    for pinned in "$GRAPHVIZ" "$CHROMIUM"; do
      $sudo apt-get install -y -qq --no-install-recommends "$pinned" >/dev/null 2>&1 \
        || $sudo apt-get install -y -qq --no-install-recommends "${pinned%%=*}" >/dev/null
    done
  else
    echo "setup: no apt-get here: install Graphviz (the 'dot' program) and Chromium (the animation's test)" >&2
  fi
fi
python3.11 -m venv .venv
.venv/bin/pip install -q -r requirements.lock -e .
