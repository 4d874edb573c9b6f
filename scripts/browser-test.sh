#!/usr/bin/env bash
# Renders a `delaynav report` page in headless Chromium and checks it: the page loads with no
# console error and no failed load, fetches nothing from the network, and every plot is drawn
# (each `svg.plot` of the list below is laid out with a size, and holds data elements whose
# rendered boxes are not empty). A screenshot is kept under target/browser-test/.
#
#   scripts/browser-test.sh [REPORT.html]
#
# Without REPORT, builds the command and writes the report of log171.bin
# (../shared/data/ardupilot-log171, or $DELAYNAV_SHARED_DATA/ardupilot-log171) to
# target/browser-test/report.html. Chromium: $CHROMIUM, else /usr/bin/chromium (Debian's
# `chromium`; `.ci/run` installs it when absent). Exits non-zero on any failed check.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
out=target/browser-test
mkdir -p "$out"
chromium="${CHROMIUM:-/usr/bin/chromium}"
if [ ! -x "$chromium" ]; then
  echo "browser-test: $chromium not found (apt-get install -y chromium)" >&2
  exit 1
fi

report="${1:-}"
if [ -z "$report" ]; then
  data="${DELAYNAV_SHARED_DATA:-../shared/data}/ardupilot-log171/log171.bin"
  [ -f "$data" ] || { echo "browser-test: $data is missing" >&2; exit 1; }
  # The command CI's "examples compile" step runs: already built there.
  cargo build --release --workspace --all-features --examples --bins
  report="$out/report.html"
  "${CARGO_TARGET_DIR:-target}/release/delaynav" report "$data" -o "$report" --quiet >/dev/null
fi
[ -f "$report" ] || { echo "browser-test: $report not found" >&2; exit 1; }

# Self-contained: no address to fetch (the SVG namespace is a name, never loaded).
if grep -oE '(src|href)="(https?:)?//[^"]*"' "$report" | head -1 | grep -q .; then
  echo "browser-test: the report loads something from the network" >&2
  exit 1
fi

profile="$(mktemp -d)"
trap 'rm -rf "$profile"' EXIT
# The flags that work on this machine's closed network (docs/cli.md).
flags=(--headless --no-sandbox --disable-gpu --disable-quic --no-first-run
  --disable-background-networking --disable-component-update --disable-sync
  --hide-scrollbars --user-data-dir="$profile" --enable-logging=stderr --v=0)
abs="$(cd "$(dirname "$report")" && pwd)/$(basename "$report")"

# 1. The page as it is: a screenshot, and Chromium's console log.
"$chromium" "${flags[@]}" --window-size=1000,5200 --screenshot="$root/$out/report.png" \
  "file://$abs" >"$out/screenshot.log" 2>&1 || { cat "$out/screenshot.log" >&2; exit 1; }
[ -s "$out/report.png" ] || { echo "browser-test: no screenshot" >&2; exit 1; }

# 2. The same page with a probe appended: it records every error event (script errors and
#    failed loads, captured) and console.error call from the start, and after load measures
#    each plot; the DOM is then dumped with the probe's result in it.
probe="$out/probe.html"
python3 - "$report" "$probe" <<'EOF'
import sys
page = open(sys.argv[1], encoding="utf-8").read()
hook = """<script>
window.__errors = [];
addEventListener('error', e => __errors.push(String(e.message || (e.target && (e.target.src || e.target.href)) || 'error')), true);
const __ce = console.error; console.error = (...a) => { __errors.push(a.join(' ')); __ce(...a); };
</script>"""
measure = """<script>
addEventListener('load', () => {
  const plots = [...document.querySelectorAll('svg.plot')].map(svg => {
    const box = svg.getBoundingClientRect();
    const data = [...svg.querySelectorAll('polyline.series, polygon.band, g.dots rect, rect.on, rect.off')];
    const drawn = data.filter(el => { const b = el.getBBox(); return b.width > 0 || b.height > 0; });
    const points = svg.querySelectorAll('polyline.series').length
      ? [...svg.querySelectorAll('polyline.series')].reduce((n, p) => n + p.points.numberOfItems, 0)
      : drawn.length;
    return {name: svg.dataset.plot, width: box.width, height: box.height, drawn: drawn.length, points};
  });
  const pre = document.createElement('pre');
  pre.id = 'browser-test-result';
  pre.textContent = JSON.stringify({errors: window.__errors, plots});
  document.body.appendChild(pre);
});
</script>"""
page = page.replace("<head>", "<head>" + hook, 1).replace("</body>", measure + "</body>", 1)
open(sys.argv[2], "w", encoding="utf-8").write(page)
EOF
probe_abs="$(cd "$(dirname "$probe")" && pwd)/$(basename "$probe")"
"$chromium" "${flags[@]}" --window-size=1000,1200 --virtual-time-budget=5000 --dump-dom \
  "file://$probe_abs" >"$out/dom.html" 2>"$out/dump.log" || { cat "$out/dump.log" >&2; exit 1; }

python3 - "$out/dom.html" "$out/screenshot.log" "$out/dump.log" <<'EOF'
import html, json, re, sys
dom = open(sys.argv[1], encoding="utf-8").read()
m = re.search(r'<pre id="browser-test-result">(.*?)</pre>', dom, re.S)
if not m:
    sys.exit("browser-test: the probe did not run (no result in the DOM)")
result = json.loads(html.unescape(m.group(1)))
failures = []
# Console errors: the probe's, and any Chromium logged for the page (CONSOLE lines at ERROR
# level, uncaught exceptions, failed loads).
failures += [f"console error: {e}" for e in result["errors"]]
for log in sys.argv[2:]:
    for line in open(log, encoding="utf-8", errors="replace"):
        if ("CONSOLE" in line and ":ERROR:" in line) or "Uncaught" in line \
                or "Failed to load resource" in line:
            failures.append(f"console: {line.strip()}")
expected = ["attitude-roll", "attitude-pitch", "attitude-yaw", "delay", "delay-status",
            "innovations-gps", "innovations-mag", "health", "track"]
by = {p["name"]: p for p in result["plots"]}
for name in expected:
    p = by.get(name)
    if p is None:
        failures.append(f"plot {name}: missing")
    elif p["width"] < 100 or p["height"] < 50:
        failures.append(f"plot {name}: laid out {p['width']}x{p['height']}")
    elif p["drawn"] == 0 or p["points"] < 2:
        failures.append(f"plot {name}: nothing drawn ({p['drawn']} elements, {p['points']} points)")
    else:
        print(f"plot {name:<16} {p['width']:.0f}x{p['height']:.0f} px, "
              f"{p['drawn']} elements drawn, {p['points']} points")
if failures:
    sys.exit("browser-test FAILED:\n  " + "\n  ".join(failures))
print(f"browser-test: {len(expected)} plots drawn, no console error")
EOF
echo "screenshot: $out/report.png"
