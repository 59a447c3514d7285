#!/bin/sh
# gen_keys_doc.sh - rewrites the key list of proto/PROTOCOL.md, the lines
# between its two markers, from `skyd --list-keys --markdown`; with --check
# it only says whether the list is current (the test test_keys_doc), and
# exits 1 with a diff when it is not.
#   usage: tools/gen_keys_doc.sh [--check] SKYD [PROTOCOL.md]
set -eu
check=0
if [ "${1:-}" = "--check" ]; then
	check=1
	shift
fi
skyd=${1:?usage: tools/gen_keys_doc.sh [--check] SKYD [PROTOCOL.md]}
doc=${2:-$(cd "$(dirname "$0")/.." && pwd)/proto/PROTOCOL.md}
begin='<!-- keys: begin; tools/gen_keys_doc.sh writes this list from skyd --list-keys --markdown -->'
end='<!-- keys: end -->'
list=$(mktemp)
new=$(mktemp)
trap 'rm -f "$list" "$new"' EXIT
"$skyd" --list-keys --markdown >"$list"
if [ "$(grep -cxF "$begin" "$doc")" != 1 ] || [ "$(grep -cxF "$end" "$doc")" != 1 ]; then
	echo "gen_keys_doc.sh: $doc needs the lines '$begin' and '$end' once each" >&2
	exit 2
fi
awk -v b="$begin" -v e="$end" -v f="$list" '
	$0 == b { print; while ((getline l < f) > 0) print l; skip = 1; next }
	$0 == e { skip = 0 }
	!skip { print }' "$doc" >"$new"
if [ "$check" = 1 ]; then
	if ! cmp -s "$doc" "$new"; then
		diff -u "$doc" "$new" || true
		echo "gen_keys_doc.sh: $doc's key list is not skyd's; run tools/gen_keys_doc.sh $skyd" >&2
		exit 1
	fi
	exit 0
fi
cat "$new" >"$doc"
