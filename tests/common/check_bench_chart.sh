#!/usr/bin/env bash
# check_bench_chart.sh OUT.svg MIN_MARKS CMD ARGS...: runs a benchmark that writes the chart OUT.svg
# (its --chart argument, given in ARGS) and checks the chart: the command exits 0, OUT.svg is written
# afresh, parses as SVG (python3 XML), holds no "nan"/"inf" and at least MIN_MARKS data markers
# (series points and named points). Exit 77 (the command's "no device" code) is passed on: a skip.
set -uo pipefail
out=$1 min_marks=$2
shift 2
rm -f "$out"
mkdir -p "$(dirname "$out")"
"$@" >"$out.stdout" 2>"$out.stderr"
rc=$?
if [ $rc -eq 77 ]; then
  echo "skipped: $1 exited 77 (no device)"; cat "$out.stderr"; exit 77
fi
if [ $rc -ne 0 ]; then
  echo "FAIL: $* exited $rc"; tail -20 "$out.stdout" "$out.stderr"; exit 1
fi
/usr/bin/python3 - "$out" "$min_marks" <<'EOF'
import re, sys, xml.etree.ElementTree as ET
path, min_marks = sys.argv[1], int(sys.argv[2])
text = open(path, encoding="utf-8").read()
root = ET.fromstring(text)
assert root.tag == "{http://www.w3.org/2000/svg}svg", f"root is {root.tag}"
bad = re.search(r"(^|[^a-zA-Z])-?(nan|inf)([^a-zA-Z]|$)", text, re.I)
assert not bad, f"non-finite number near: {text[max(0, bad.start() - 80):bad.end() + 40]!r}"
ns = "{http://www.w3.org/2000/svg}"
marks = [e for e in root.iter() if e.get("class") in ("pt", "named")]
assert len(marks) >= min_marks, f"{len(marks)} markers, expected at least {min_marks}"
for e in marks:  # every marker inside the drawing
    x = float(e.get("cx", e.get("x")))
    y = float(e.get("cy", e.get("y")))
    assert 0 <= x <= float(root.get("width")) and 0 <= y <= float(root.get("height")), (x, y)
print(f"{path}: valid SVG, {len(marks)} markers")
EOF
