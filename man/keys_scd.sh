#!/bin/sh
# keys_scd.sh - writes skyd.conf(5)'s scdoc source with the sky's keys from
# `skyd --list-keys` in place of its %KEYS% line, so that the page lists
# exactly the keys the daemon takes.
#   usage: man/keys_scd.sh SKYD IN.scd OUT.scd
set -eu
skyd=$1 in=$2 out=$3
grep -qx '%KEYS%' "$in" || { echo "keys_scd.sh: $in has no %KEYS% line" >&2; exit 1; }
list=$(mktemp)
trap 'rm -f "$list"' EXIT
# Columns: name, unit, range, default, tables recomputed, what it is.
# scdoc reads * _ \ as markup: escape them in the text that comes from skyd.
"$skyd" --list-keys | awk -F'\t' '
	function esc(s) { gsub(/\\/, "\\\\", s); gsub(/\*/, "\\*", s); gsub(/_/, "\\_", s); return s }
	NF == 6 {
		unit = ($2 == "-") ? "" : " (" esc($2) ")"
		printf "*%s*%s\n", esc($1), unit
		printf "\t%s. Values: %s; default: %s; recomputes: %s.\n\n", esc($6), esc($3), esc($4), esc($5)
	}' >"$list"
[ -s "$list" ] || { echo "keys_scd.sh: $skyd --list-keys printed nothing" >&2; exit 1; }
awk -v f="$list" '$0 == "%KEYS%" { while ((getline l < f) > 0) print l; next } { print }' "$in" >"$out.tmp"
mv "$out.tmp" "$out"
