#!/usr/bin/env bash
# Render a polarid HTML report in headless Chromium and check it.
#
#   scripts/check_report.sh REPORT.html OUT.png
#
# Checks that the page loads without script or console errors and that every <img>
# decodes (complete, naturalWidth > 0), then writes a screenshot to OUT.png.
# The check runs on a copy of the report in a temporary directory, with a small probe
# script injected at the top of <head>, so it also proves the report is self-contained
# (it may not refer to files beside it). The screenshot is taken of the report itself.
#
# Exit status: 0 passed (or skipped), 1 check failed, 2 usage.
# Without Chromium it prints "SKIPPED: chromium not installed" and exits 0, unless
# POLARID_REQUIRE_BROWSER=1. Install it with `apt-get install -y chromium`.
#
# Environment: CHROMIUM (browser binary), WINDOW_SIZE (default 1200,2000),
# SCALE (device scale factor, default 1), MIN_IMAGES (default 1),
# TIMEOUT (seconds per browser run, default 120).
set -euo pipefail

if [[ $# -ne 2 ]]; then
    echo "usage: $0 REPORT.html OUT.png" >&2
    exit 2
fi
report=$1
out=$2
if [[ ! -f "$report" ]]; then
    echo "check_report: $report: no such file" >&2
    exit 2
fi

browser=${CHROMIUM:-}
if [[ -z "$browser" ]]; then
    for b in chromium chromium-browser google-chrome; do
        if command -v "$b" >/dev/null 2>&1; then
            browser=$(command -v "$b")
            break
        fi
    done
fi
if [[ -z "$browser" ]]; then
    if [[ "${POLARID_REQUIRE_BROWSER:-0}" == 1 ]]; then
        echo "check_report: FAILED: chromium not installed (POLARID_REQUIRE_BROWSER=1)" >&2
        exit 1
    fi
    echo "SKIPPED: chromium not installed"
    exit 0
fi

abs() { (cd "$(dirname "$1")" && printf '%s/%s\n' "$(pwd -P)" "$(basename "$1")"); }
report_abs=$(abs "$report")
mkdir -p "$(dirname "$out")"
out_abs=$(abs "$out")
rm -f "$out_abs"

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
timeout_s=${TIMEOUT:-120}

# Flags for a closed network and a throw-away profile (see the machine notes).
run_browser() {
    local profile
    profile=$(mktemp -d "$work/profile.XXXXXX")
    timeout "$timeout_s" "$browser" --headless --no-sandbox --disable-gpu --disable-quic \
        --no-first-run --disable-background-networking --disable-component-update \
        --disable-sync --disable-extensions --hide-scrollbars --mute-audio \
        --user-data-dir="$profile" "$@"
}

# 1. The probe: records script errors, failed resource loads, console.error calls and
#    the decoding state of every image into a <div id="polarid-check"> on `load`.
cat >"$work/probe.html" <<'EOF'
<script>
(function () {
  var errors = [];
  window.addEventListener('error', function (e) {
    var t = e.target;
    if (t && t !== window && (t.src || t.href)) {
      errors.push('failed to load ' + String(t.src || t.href).slice(0, 80));
    } else {
      errors.push('error: ' + e.message);
    }
  }, true);
  var ce = console.error;
  console.error = function () {
    errors.push('console.error: ' + Array.prototype.join.call(arguments, ' '));
    return ce.apply(console, arguments);
  };
  window.addEventListener('load', function () {
    var imgs = Array.prototype.slice.call(document.images);
    var broken = imgs.filter(function (i) { return !(i.complete && i.naturalWidth > 0); });
    broken.forEach(function (i) {
      errors.push('image not decoded: ' + (i.alt || String(i.src).slice(0, 60)));
    });
    var d = document.createElement('div');
    d.id = 'polarid-check';
    d.setAttribute('data-images', String(imgs.length));
    d.setAttribute('data-broken', String(broken.length));
    d.setAttribute('data-errors', String(errors.length));
    d.textContent = errors.join(' || ');
    document.body.appendChild(d);
  });
})();
</script>
EOF
copy="$work/report.html"
if grep -qi '<head[ >]' "$report_abs"; then
    awk -v probe="$work/probe.html" '
        { print }
        !done && tolower($0) ~ /<head[ >]/ {
            while ((getline line < probe) > 0) print line
            done = 1
        }' "$report_abs" >"$copy"
else
    cat "$work/probe.html" "$report_abs" >"$copy"
fi

run_browser --enable-logging=stderr --v=0 --virtual-time-budget=10000 \
    --dump-dom "file://$copy" >"$work/dom.html" 2>"$work/browser.log" || {
    echo "check_report: FAILED: the browser could not load the report (status $?)" >&2
    tail -n 20 "$work/browser.log" >&2
    exit 1
}

probe_line=$(grep -o '<div id="polarid-check"[^>]*>[^<]*' "$work/dom.html" || true)
if [[ -z "$probe_line" ]]; then
    echo "check_report: FAILED: the page did not finish loading (no probe result in the DOM)" >&2
    tail -n 20 "$work/browser.log" >&2
    exit 1
fi
attr() { sed -n "s/.*$1=\"\\([0-9]*\\)\".*/\\1/p" <<<"$probe_line"; }
images=$(attr data-images)
broken=$(attr data-broken)
errors=$(attr data-errors)
messages=${probe_line#*>}
# Uncaught exceptions also appear in the browser's log as CONSOLE lines.
uncaught=$(grep -c 'CONSOLE.*Uncaught' "$work/browser.log" || true)

fail=0
echo "check_report: $report: $images images, $broken not decoded, $errors errors"
if [[ "$images" -lt "${MIN_IMAGES:-1}" ]]; then
    echo "check_report: FAILED: expected at least ${MIN_IMAGES:-1} images, found $images" >&2
    fail=1
fi
if [[ "$broken" != 0 || "$errors" != 0 || "$uncaught" != 0 ]]; then
    echo "check_report: FAILED: $messages" >&2
    grep 'CONSOLE' "$work/browser.log" >&2 || true
    fail=1
fi

# 2. The screenshot, of the report as it is.
run_browser --window-size="${WINDOW_SIZE:-1200,2000}" \
    --force-device-scale-factor="${SCALE:-1}" --virtual-time-budget=10000 \
    --screenshot="$out_abs" "file://$report_abs" >"$work/shot.log" 2>&1 || true
if [[ ! -s "$out_abs" ]]; then
    echo "check_report: FAILED: no screenshot was written to $out" >&2
    tail -n 20 "$work/shot.log" >&2
    exit 1
fi
echo "check_report: screenshot $out ($(wc -c <"$out_abs") bytes)"

if [[ $fail != 0 ]]; then
    exit 1
fi
echo "check_report: passed"
