#!/bin/sh
# accuracy_doc.sh - writes docs/accuracy.md from the output of `skybench
# accuracy`: a short header that links to the findings (docs/findings.md,
# prose written from the figures), then the generated tables verbatim; copies
# the plot, the fisheye images and the CSV to docs/accuracy/.
#   usage: tools/accuracy_doc.sh OUT_DIR "machine description"
set -eu
out=${1:?usage: tools/accuracy_doc.sh OUT_DIR "machine description"}
machine=${2:?usage: tools/accuracy_doc.sh OUT_DIR "machine description"}
root=$(cd "$(dirname "$0")/.." && pwd)
docs=$root/docs
mkdir -p "$docs/accuracy"
cp "$out/accuracy.csv" "$out/errtime.png" "$docs/accuracy/"
for f in "$out"/fisheye-*.png; do
	[ -e "$f" ] && cp "$f" "$docs/accuracy/"
done
{
	cat <<'HEADER'
# Accuracy of the sky tables against a path-traced ground truth

The sky radiance a client reads from the published sky-view table, sampled
with `proto/skysample.h` as libsky does, against the CPU path tracer
(`truth/pt.c`), for a matrix of scenes and for every quality preset and a
sweep of each knob, put against the engine's run time. Written by
`tools/accuracy_doc.sh` from the output of `build/tools/skybench accuracy`;
do not edit by hand.

What the figures mean, whether the truth is good enough, what was changed
to reach them and what bounds the rest:
[findings.md, "Accuracy against a path-traced truth"](findings.md#accuracy-against-a-path-traced-truth).
HEADER
	printf '\n## The report\n\nMachine: %s.\n\n' "$machine"
	printf '![error against run time](accuracy/errtime.png)\n\n'
	for f in "$docs"/accuracy/fisheye-*.png; do
		[ -e "$f" ] || continue
		n=$(basename "$f" .png)
		printf '%s (left: the tables as a client samples them; middle: the path tracer; right: relative error, blue -20 %% to red +20 %%):\n\n![%s](accuracy/%s.png)\n\n' \
			"${n#fisheye-}" "$n" "$n"
	done
	cat "$out/accuracy.md"
	printf '\nPer scene and configuration: [accuracy/accuracy.csv](accuracy/accuracy.csv).\n'
} > "$docs/accuracy.md"
echo "wrote $docs/accuracy.md"
