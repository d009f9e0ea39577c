#!/usr/bin/env bash
# The report in a real browser: a short synthetic trial (the default scene cut to 20 frames: rest, loading,
# partial and full slip) is processed with every stage (channels and the model fit included) and validated;
# `tirstrain report` writes one page for it and one for it beside itself (two results), and headless
# Chromium must draw every expected figure without a console error (browser_check.mjs).
# Usage: browser_test.sh TIRSTRAIN_CLI WORK_DIR
set -euo pipefail
cli=$1
work=$2
here=$(cd "$(dirname "$0")" && pwd)
source_dir=$(cd "$here/../.." && pwd)
if [ ! -x /usr/bin/chromium ]; then echo "skipped: no /usr/bin/chromium (scripts/install-deps installs it)"; exit 77; fi
if ! command -v node > /dev/null; then echo "skipped: no node"; exit 77; fi

rm -rf "$work" && mkdir -p "$work"
sed 's/timing: {frames: 60,/timing: {frames: 20,/' "$source_dir/samples/scenes/default.yaml" > "$work/scene.yaml"
grep -q 'frames: 20,' "$work/scene.yaml" || { echo "the default scene's timing line changed: update $0"; exit 1; }
"$cli" synth --scene "$work/scene.yaml" --out "$work/trial" --quiet
"$cli" process "$work/trial" --out "$work/result" --compute channels,fit --quiet
"$cli" validate --trial "$work/trial" --result "$work/result" --out "$work/validation" --quiet > /dev/null

"$cli" report "$work/result" --validation "$work/validation" --out "$work/report.html"
node "$here/browser_check.mjs" "$work/report.html" "$work/report.png" \
  contact tracks forces maps-0-onset maps-0-t90 maps-0-full_slip energy stick fit \
  principal-directions ridge-orientation validation-0

# Two results: time series overlaid, maps and histograms side by side (the second labelled apart).
"$cli" report "$work/result" "$work/result" --out "$work/two.html"
grep -q '"result":"result (2)"' "$work/two.html" || { echo "FAIL the second result is not labelled apart"; exit 1; }
node "$here/browser_check.mjs" "$work/two.html" "$work/two.png" contact maps-0-t90 maps-1-t90 principal-directions
