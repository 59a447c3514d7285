#!/bin/sh
# scdoc.sh - makes a page's roff with scdoc, hyphenation off after the page
# header: scdoc writes .nh before .TH, which groff's man macros undo, and
# man then breaks paths such as /usr/local/share/doc/skyd at a hyphen.
#   usage: man/scdoc.sh SCDOC IN.scd OUT
set -eu
scdoc=$1 in=$2 out=$3
"$scdoc" <"$in" >"$out.tmp"
sed -i '/^\.TH /a .nh' "$out.tmp"
mv "$out.tmp" "$out"
