#!/usr/bin/env bash
# Looks at a report page as a person would: headless Chromium opens
# DIR/index.html and saves what a desktop window (1280 wide) and a phone
# (390 wide) show of it, the whole page long, as DIR/screenshot_desktop.png
# and DIR/screenshot_phone.png.
# Usage: scripts/report_screenshot.sh [DIR]   (default: report; needs Debian's chromium)
set -euo pipefail
dir=${1:-report}
[ -f "$dir/index.html" ] || { echo "report_screenshot: $dir/index.html not found (run scripts/report.sh first)" >&2; exit 1; }
browser=$(command -v chromium || command -v chromium-browser || true)
[ -n "$browser" ] || { echo "report_screenshot: chromium not found (apt-get install chromium)" >&2; exit 1; }
page="file://$(cd "$dir" && pwd)/index.html"
shot() {  # shot WIDTH HEIGHT FILE
  "$browser" --headless=new --no-sandbox --disable-gpu --hide-scrollbars --force-device-scale-factor=1 \
    --virtual-time-budget=5000 --window-size="$1,$2" --screenshot="$3" "$page" >/dev/null 2>&1
  [ -s "$3" ] || { echo "report_screenshot: chromium wrote no $3" >&2; exit 1; }
  echo "report_screenshot: $3 (${1}x$2)"
}
shot 1280 "${REPORT_SHOT_HEIGHT:-9000}" "$dir/screenshot_desktop.png"
shot 390 "${REPORT_SHOT_HEIGHT:-16000}" "$dir/screenshot_phone.png"
