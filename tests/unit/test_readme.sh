#!/bin/sh
# test_readme.sh - tests/README.md names every test that ctest lists, once,
# with the labels ctest gives it, and no test that ctest does not list, so
# that its table cannot go stale.
#   usage: test_readme.sh CTEST BUILD_DIR README
set -u
export LC_ALL=C
ctest=$1 build=$2 readme=$3
tmp=$(mktemp -d "${TMPDIR:-/tmp}/skyd-readme.XXXXXX")
trap 'rm -rf "$tmp"' EXIT

# "name|label label ..." per test, its labels sorted; "-" for none.
# ctest -N -V prints a test's labels on the line before its name.
(cd "$build" && "$ctest" -N -V) | awk '
	/^Labels:/ { labels = $0; sub(/^Labels: */, "", labels); next }
	/^ *Test +#[0-9]+: / {
		n = split(labels, l, " ")
		for (i = 2; i <= n; i++)
			for (j = i; j > 1 && l[j - 1] > l[j]; j--) { t = l[j]; l[j] = l[j - 1]; l[j - 1] = t }
		s = n ? l[1] : "-"
		for (i = 2; i <= n; i++) s = s " " l[i]
		print $NF "|" s
		labels = ""
	}' | sort > "$tmp/ctest"
# The same from the rows of the table under "## Every test":
# | `name` | label, label | needs | proves |
awk -F'|' '/^## / { table = ($0 ~ /^## Every test/) }
	table && /^\| `[^`]+` \|/ {
		name = $2; gsub(/[ `]/, "", name)
		n = split($3, l, ",")
		for (i = 1; i <= n; i++) gsub(/ /, "", l[i])
		for (i = 2; i <= n; i++)
			for (j = i; j > 1 && l[j - 1] > l[j]; j--) { t = l[j]; l[j] = l[j - 1]; l[j - 1] = t }
		s = n && l[1] != "" ? l[1] : "-"
		for (i = 2; i <= n; i++) s = s " " l[i]
		print name "|" s
	}' "$readme" | sort > "$tmp/readme"

cut -d'|' -f1 "$tmp/ctest" | sort > "$tmp/ctest.names"
cut -d'|' -f1 "$tmp/readme" | sort > "$tmp/readme.names"
{
	sort -u "$tmp/readme.names" | comm -23 "$tmp/ctest.names" - | sed 's/.*/& is a ctest test without a row/'
	sort -u "$tmp/readme.names" | comm -13 "$tmp/ctest.names" - |
		sed 's/.*/the row of & names no test that ctest lists/'
	uniq -d "$tmp/readme.names" | sed 's/.*/& has more than one row/'
	sort -t '|' -k1,1 "$tmp/ctest" > "$tmp/ctest.byname"
	sort -t '|' -k1,1 "$tmp/readme" > "$tmp/readme.byname"
	join -t '|' "$tmp/ctest.byname" "$tmp/readme.byname" | awk -F'|' '$2 != $3 {
		printf "%s is labelled \"%s\", its row says \"%s\"\n", $1, $2, $3 }'
} | sed "s|^|FAIL: $readme: |" > "$tmp/problems"
cat "$tmp/problems"
echo "test_readme: $(wc -l < "$tmp/ctest.names") tests, $(wc -l < "$tmp/readme.names") rows"
[ ! -s "$tmp/problems" ]
