#!/usr/bin/env bash
# Installs the Debian packages the tests use when they are missing: chromium for the browser tests (Playwright's
# own browser download is not reachable here) and jq, which a documented command pipes through
# (tests/docs_commands). Needs root or password-less sudo; otherwise says what to do.
set -u
missing=()
[ -x /usr/bin/chromium ] || missing+=(chromium)
command -v jq >/dev/null 2>&1 || missing+=(jq)
[ ${#missing[@]} = 0 ] && exit 0
if [ "$(id -u)" = 0 ]; then SUDO=""; elif sudo -n true 2>/dev/null; then SUDO="sudo -n"; else
  echo "${missing[*]} missing and cannot be installed without root: the tests that need them will be skipped" \
       "(CI fails them). Install with: sudo apt-get install ${missing[*]}" >&2
  exit 0
fi
echo "installing Debian's ${missing[*]} for the tests..." >&2
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get install -y -qq "${missing[@]}" >/dev/null 2>&1 || { $SUDO apt-get update -qq && $SUDO apt-get install -y -qq "${missing[@]}"; }
