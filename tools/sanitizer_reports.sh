#!/usr/bin/env bash
# Fails when a sanitizer wrote a report during a test run of a build made
# with SKYD_SANITIZE: every test writes its processes' reports under
# BUILD/sanitizer-reports/<test>/ (tests/CMakeLists.txt). Prints each
# report, named by its test, and exits 1; 0 when there is none.
#   tools/sanitizer_reports.sh BUILD
set -euo pipefail
dir=${1:?usage: sanitizer_reports.sh BUILD}/sanitizer-reports
[ -d "$dir" ] || { echo "sanitizer_reports: no reports directory $dir: none written"; exit 0; }
found=0
while IFS= read -r -d '' f; do
	[ -s "$f" ] || continue
	rel=${f#"$dir"/}
	echo "==== ${rel%%/*}: ${rel#*/}"
	cat "$f"
	found=$((found + 1))
done < <(find "$dir" -type f -print0 | sort -z)
if [ "$found" -gt 0 ]; then
	echo "sanitizer_reports: $found report(s) under $dir" >&2
	exit 1
fi
echo "sanitizer_reports: no report under $dir"
