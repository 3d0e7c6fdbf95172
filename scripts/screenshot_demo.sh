#!/usr/bin/env bash
# Renders the demo's index.html in headless Chromium and saves a screenshot, to check by eye
# that the page a person opens shows the animation, legend, pictures, tables and plots with no
# network (the page is opened from disk; Chromium is told not to reach any host).
#
#   scripts/screenshot_demo.sh [DEMO_DIR] [OUT_PNG]
#
# DEMO_DIR defaults to a fresh `evigrid demo --frames 100` in a temporary folder; OUT_PNG to
# docs/demo-index.png. Needs Chromium (Debian: `apt-get install chromium`). Not run in CI: the
# browser is a large install and the check is a picture for people, kept in docs/.
set -euo pipefail
cd "$(dirname "$0")/.."
browser="$(command -v chromium || command -v chromium-browser || command -v google-chrome || true)"
if [ -z "$browser" ]; then
  echo "screenshot_demo: no Chromium found (Debian: apt-get install chromium)" >&2
  exit 1
fi
dir="${1:-}"
out="${2:-docs/demo-index.png}"
case "$out" in /*) ;; *) out="$(pwd)/$out" ;; esac
if [ -z "$dir" ]; then
  dir="$(mktemp -d)/demo"
  cargo run --release -q -p evigrid-cli -- demo --frames 100 --out "$dir" > /dev/null
fi
page="$(cd "$dir" && pwd)/index.html"
[ -f "$page" ] || { echo "screenshot_demo: $page missing" >&2; exit 1; }
# --host-resolver-rules maps every host to nowhere, so a page that fetched anything from a
# network would show it broken in the screenshot.
"$browser" --headless --no-sandbox --disable-gpu --hide-scrollbars \
  --host-resolver-rules="MAP * ~NOTFOUND" \
  --window-size=1400,3400 --screenshot="$out" "file://$page" 2> /dev/null
echo "screenshot of $page in $out"
