#!/usr/bin/env bash
# Everything the test command needs on a fresh machine, in one place: the README's test
# command and .ci/run both call this script, so they cannot drift.
#   1. Debian's chromium for the viewer and report tests (Playwright drives it headless and
#      never downloads a browser of its own), when no chromium is on the machine yet;
#   2. reachwise with its development extra (linters, type checker, test tools, the real
#      robot descriptions), editable.
# Run it from anywhere; it works on the checkout it lives in.
set -euo pipefail
cd "$(dirname "$0")/.."

if ! command -v chromium >/dev/null 2>&1 && [ ! -x /usr/bin/chromium ]; then
  if ! command -v apt-get >/dev/null 2>&1; then
    echo "install-test-deps: no chromium and no apt-get: install Chromium with your" \
         "package manager (the browser tests look for 'chromium' on PATH)" >&2
    exit 1
  fi
  sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    sudo="sudo"
  fi
  echo "install-test-deps: installing Debian's chromium (apt-get)" >&2
  $sudo apt-get update -qq
  $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
fi

python3 -m pip install -q -e ".[dev]"
