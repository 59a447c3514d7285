#!/usr/bin/env bash
# test_accuracy_truth.sh - the committed ground truth is the truth of the
# scenes as they are now: every file `skybench accuracy --list-truth`
# names for the CI's matrix and for the shadowed scenes is in
# tests/accuracy_gt. A change to a scene or to the tracer's settings moves
# its hash; without this check, test_accuracy and test_accuracy_shadow
# would quietly run the tracer for minutes to hours instead. Listing
# needs no device and writes nothing.
set -u
skybench=$1
gt=$2
fail=0
tmp=$(mktemp -d "${TMPDIR:-/tmp}/skyd-truth.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
cd "$tmp" || exit 1

for matrix in "--reduced" "--configs medium --scenes shadow-"; do
	# shellcheck disable=SC2086 # the matrix's words are separate options
	if ! "$skybench" accuracy $matrix --list-truth >list 2>err; then
		echo "FAIL: skybench accuracy $matrix --list-truth: $(cat err)"
		fail=1
		continue
	fi
	n=0
	while read -r scene kind file; do
		n=$((n + 1))
		if [ -s "$gt/$file" ]; then
			echo "ok: $scene ($kind): $file"
		else
			echo "FAIL: $scene ($kind): $file is not in $gt (run skybench accuracy $matrix --cache $gt)"
			fail=1
		fi
	done <list
	if [ "$n" -eq 0 ]; then
		echo "FAIL: $matrix lists no truth"
		fail=1
	fi
done
rm -f list err
if [ -n "$(ls -A)" ]; then
	echo "FAIL: --list-truth wrote into the working directory: $(ls -A)"
	fail=1
fi
exit $fail
