#!/usr/bin/env bash
# Installs the browser the report's browser test drives: Debian's `chromium` (headless),
# with the DejaVu fonts the page and its screenshot are set in.
#
# The report test (`cargo nextest run -p fogline-report browser`) opens the generated HTML page
# in /usr/bin/chromium over the DevTools protocol and fails when it is missing. This machine
# has no other way to get a browser than Debian's package. Idempotent and quiet: does nothing
# when /usr/bin/chromium exists; otherwise runs `apt-get update` and installs the package
# (needs root, or sudo without a password). Prints the browser's path on stdout.
#
#   scripts/browser-deps.sh
#
# FOGLINE_CHROMIUM=/path/to/chromium skips the install and is used by the test instead.
set -euo pipefail

if [ -n "${FOGLINE_CHROMIUM:-}" ]; then
    if [ ! -x "$FOGLINE_CHROMIUM" ]; then
        echo "FOGLINE_CHROMIUM=$FOGLINE_CHROMIUM is not an executable" >&2
        exit 1
    fi
    echo "$FOGLINE_CHROMIUM"
    exit 0
fi

browser=/usr/bin/chromium
if [ ! -x "$browser" ]; then
    sudo=""
    if [ "$(id -u)" != 0 ]; then
        if command -v sudo >/dev/null 2>&1; then
            sudo="sudo -n"
        else
            echo "$browser is missing and this is not root: install Debian's chromium package" >&2
            exit 1
        fi
    fi
    echo "installing Debian's chromium (apt-get)" >&2
    export DEBIAN_FRONTEND=noninteractive
    $sudo apt-get update -qq >&2
    $sudo apt-get install -y -qq --no-install-recommends chromium fonts-dejavu-core >/dev/null
fi
if [ ! -x "$browser" ]; then
    echo "apt-get finished but $browser is still missing" >&2
    exit 1
fi
if ! "$browser" --version >/dev/null 2>&1; then
    echo "$browser is installed but does not run (try: $browser --version)" >&2
    exit 1
fi
echo "$browser"
