#!/bin/sh
# accuracy_doc.sh - writes docs/accuracy.md from the output of `skybench
# accuracy`: a short header that links to the findings (docs/findings/,
# prose written from the figures), then the generated tables verbatim; copies
# the plots, the fisheye images and the CSV to docs/accuracy/.
#   usage: tools/accuracy_doc.sh --run [BUILD_DIR]
#          tools/accuracy_doc.sh OUT_DIR "machine description"
# --run runs the report's own command first in BUILD_DIR, where skybench was
# built (absolute or from the repository's root; build/ by default), and
# describes the machine itself. The truth is cached in BUILD_DIR/acc-gt: the
# first run traces it (about 15 minutes on the 2-core machine, loaded), later
# runs only recompute the tables (about 5 minutes).
set -eu
root=$(cd "$(dirname "$0")/.." && pwd)
if [ "${1:-}" = --run ]; then
	cd "$root"
	build=${2:-build}
	out=$build/acc-doc
	mkdir -p "$out"
	"$build/tools/skybench" accuracy --out "$out" --cache "$build/acc-gt" \
		--day-error 0.02 --twilight-error 0.05 --max-samples 262144 \
		--fisheye-n 24 --fisheye-error 0.08
	cpu=$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -n 1)
	machine="$(nproc) cores ($cpu), $(sed -n 's/^# device: //p' "$out/accuracy.csv")"
else
	out=${1:?usage: tools/accuracy_doc.sh --run [BUILD_DIR] | OUT_DIR "machine description"}
	machine=${2:?usage: tools/accuracy_doc.sh --run [BUILD_DIR] | OUT_DIR "machine description"}
fi
docs=$root/docs
mkdir -p "$docs/accuracy"
cp "$out/accuracy.csv" "$out/errtime.png" "$out/errtime-rgb.png" "$docs/accuracy/"
for f in "$out"/fisheye-*.png; do
	[ -e "$f" ] && cp "$f" "$docs/accuracy/"
done
{
	cat <<'HEADER'
# Accuracy of the sky tables against a path-traced ground truth

The sky radiance a client reads from the published sky-view table, sampled
with `proto/skysample.h` as libsky does, against the CPU path tracer
(`truth/pt.c`), for a matrix of scenes and observers and for every quality
preset and a sweep of each knob, put against the engine's run time: the
error of luminance, of each channel and of chromaticity. Written by
`tools/accuracy_doc.sh --run` (which runs `build/tools/skybench accuracy`
and keeps the truth it traced in `build/acc-gt`, so a second run takes
minutes); do not edit by hand.

What the figures mean, whether the truth is good enough, what was changed
to reach them and what bounds the rest:
[findings/shaders.md, "Accuracy against a path-traced truth"](findings/shaders.md#accuracy-against-a-path-traced-truth)
and, for colour and the observers,
[findings/tools.md, "Colour and observers from the ground to orbit"](findings/tools.md#colour-and-observers-from-the-ground-to-orbit).
The shadowed scenes (`shadow-*`: the sun behind a broken layer, a low sun
through scattered cumulus, an overcast at 300 m, a ridge at sunset, an
observer at 12 km above a layer) and their categories (lit, shadow,
shafts) are explained in the report below; their goal is a mean
luminance error of at most 10 % in each category by day. Their truth at
skybench's own settings is committed in `tests/accuracy_gt/`:
`ctest --test-dir build -R test_accuracy_shadow` runs them against it in
under a minute and holds each category to
`tests/accuracy_goals_shadow.txt`, and

    build/tools/skybench accuracy --configs medium --scenes shadow- \
        --cache-ro tests/accuracy_gt --out build/accuracy-shadow --no-images

writes their report. How they read before the layers' own light and the
delta-scaled beam, and why:
[findings/shaders.md, "The sky under clouds"](findings/shaders.md#the-sky-under-clouds-what-the-shadows-left-out).
HEADER
	printf '\n## The report\n\nMachine: %s.\n\n' "$machine"
	printf '![error against run time](accuracy/errtime.png)\n\n'
	printf '![colour error against run time](accuracy/errtime-rgb.png)\n\n'
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
