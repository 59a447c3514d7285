#!/usr/bin/env bash
# test_cli.sh - skyd's offline modes as a user runs them: bad input refused
# with exit 2 before any GPU work, a dump with every file, a missing driver
# reported in one line.
set -u
skyd=$1
fail=0
check() { if ! eval "$2"; then echo "FAIL: $1"; fail=1; else echo "ok: $1"; fi; }

if ! "$skyd" --list-devices >/dev/null 2>&1; then
	echo "skipped: no Vulkan device"
	exit 77
fi
tmp=$(mktemp -d "${TMPDIR:-/tmp}/skyd-cli.XXXXXX")
trap 'rm -rf "$tmp"' EXIT

for bad in bogus_key=1 sun_elevation_deg=nan sun_elevation_deg=inf top_radius_km=6000 \
	   rayleigh_scattering_per_km=-1 skyview_width=0 aerial_width=100000 mie_g=1 \
	   ground_albedo=2 multiscatter_dirs=3; do
	key=${bad%%=*}
	"$skyd" --once "$bad" >"$tmp/out" 2>"$tmp/err"
	rc=$?
	check "$bad exits 2" "[ $rc -eq 2 ]"
	check "$bad names $key" "grep -q '$key' '$tmp/err'"
done

"$skyd" --once --dump "$tmp/d" sun_elevation_deg=5 preset=mars skyview_width=64 skyview_height=36 >"$tmp/out" 2>&1
check "dump exits 0" "[ $? -eq 0 ]"
for t in transmittance multiscatter skyview aerial; do
	check "$t.exr written" "[ -s '$tmp/d/$t.exr' ]"
	check "$t.png written" "[ -s '$tmp/d/$t.png' ]"
done
check "manifest is JSON with the state and times" \
	"python3 -c 'import json,sys; m=json.load(open(sys.argv[1])); assert m[\"state\"][\"preset\"]==\"mars\"; assert m[\"tables\"][2][\"width\"]==64; assert all(t[\"compute_ms\"]>=0 for t in m[\"tables\"])' '$tmp/d/manifest.json'"
check "manifest says each preview's axes, the sky-view's zenith at the top" \
	"python3 -c 'import json,sys; t=json.load(open(sys.argv[1]))[\"tables\"]; assert all(x[\"png_x\"] and x[\"png_y\"] and x[\"exr_rows\"] for x in t); assert t[2][\"png_y\"].startswith(\"the zenith at the top\")' '$tmp/d/manifest.json'"

# Float16 storage holds every sky: each table's scale keeps Mars' sky-view,
# above the half's 65504 cd/m2, finite, and the night's radiance, below its
# normal range, precise; so nothing is said.
for args in "preset=mars" "quality=low preset=mars" "sun_elevation_deg=-18" \
	    "sun_elevation_deg=-18 moon_elevation_deg=30 moon_illuminance_lx=0.25" \
	    "preset=mars sun_elevation_deg=-6" ""; do
	"$skyd" --once storage=f16 $args >"$tmp/out" 2>"$tmp/err"
	rc=$?
	check "f16 ${args:-on the default Earth} exits 0 and does not warn" \
		"[ $rc -eq 0 ] && ! grep -q 'storage=f16' '$tmp/err'"
done

VK_DRIVER_FILES=$tmp/none.json VK_ICD_FILENAMES=$tmp/none.json "$skyd" --once >"$tmp/out" 2>"$tmp/err"
rc=$?
check "no driver exits non-zero" "[ $rc -ne 0 ]"
check "no driver says so in one line" "[ \$(wc -l <'$tmp/err') -eq 1 ] && grep -qi 'vulkan' '$tmp/err'"
"$skyd" --once --device no-such-gpu >"$tmp/out" 2>"$tmp/err"
check "unknown device exits 1 and names it" "[ $? -eq 1 ] && grep -q 'no-such-gpu' '$tmp/err'"

[ $fail -eq 0 ] && echo "test_cli: all passed"
exit $fail
