#!/usr/bin/env bash
# Make sure Debian's Chromium is installed for the browser tests (tests/ui/*browser*).
# Playwright is used with executable_path=/usr/bin/chromium: it never downloads a browser.
set -euo pipefail
if command -v chromium >/dev/null 2>&1; then
    exit 0
fi
if [ "$(id -u)" -ne 0 ]; then
    if command -v sudo >/dev/null 2>&1; then SUDO=sudo; else
        echo "chromium is missing and this user cannot install it: run 'apt-get install chromium' as root" >&2
        exit 1
    fi
else
    SUDO=
fi
echo "installing Debian chromium for the browser tests..."
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null
command -v chromium >/dev/null
