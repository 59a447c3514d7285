#!/usr/bin/env bash
# test_install.sh - `cmake --install` into a DESTDIR as a packager runs it:
# every file where it belongs and nothing else, libsky's SONAME, headers
# that compile alone, man pages that render, the example config that skyd
# accepts; then a tiny client built once through pkg-config and once through
# the CMake package, against DESTDIR's libsky, run against the installed
# skyd (served by test_units_notify's "with" scenario).
#   usage: test_install.sh BUILD_DIR WITH_SKYD
# The install directories come from BUILD_DIR/install-dirs.env (the
# top-level CMakeLists.txt): PREFIX BINDIR LIBDIR INCLUDEDIR SYSCONFDIR
# MANDIR DOCDIR UNITDIR SYSUSERSDIR TMPFILESDIR UDEVRULESDIR, all absolute,
# as the build was configured (/usr: SYSCONFDIR /etc; /usr/local:
# /usr/local/etc), and RUNPATH, the programs' (empty where libsky lands in
# a directory of the system's own).
set -u
build=$1
with_skyd=$2
. "$build/install-dirs.env"
fail=0
check() { if eval "$2"; then echo "ok: $1"; else echo "FAIL: $1"; fail=1; fi; }

for tool in cmake cc pkg-config readelf; do
	command -v "$tool" >/dev/null || { echo "skipped: $tool is missing"; exit 77; }
done
# The man pages as a reader sees them (MANWIDTH wide).
man_text() { MANWIDTH=$1 man -l "$dest$MANDIR/$2" 2>/dev/null; }
man_names_paths() {
	local p text
	text=$(man_text 200 man8/skyd.8)
	for p in "$SYSCONFDIR/skyd/skyd.conf" "$UNITDIR/skyd.service" "$SYSUSERSDIR/skyd.conf" \
		"$TMPFILESDIR/skyd.conf" "$UDEVRULESDIR/70-skyd-sensor.rules" "$DOCDIR/PROTOCOL.md"; do
		grep -qF -- "$p" <<<"$text" || { echo "skyd(8) lacks $p"; return 1; }
	done
}
# Every path of skyd's files the pages name starts with its configured directory.
man_no_other_prefix() {
	local m p bad=0
	for m in man8/skyd.8 man1/skyctl.1 man5/skyd.conf.5 man3/libsky.3; do man_text 200 "$m"; done |
		grep -oE '/[a-z0-9/._-]*(doc/skyd|skyd/skyd\.conf|system/skyd\.|sysusers\.d|tmpfiles\.d|udev/rules\.d)' |
		sort -u >"$tmp/paths"
	while read -r p; do
		case $p in
		"$DOCDIR" | "$SYSCONFDIR/skyd/skyd.conf" | "$UNITDIR/skyd." | "$SYSUSERSDIR" | \
			"$TMPFILESDIR" | "$UDEVRULESDIR") ;;
		*) echo "a page names $p"; bad=1 ;;
		esac
	done <"$tmp/paths"
	return $bad
}
# The lines of each EXAMPLES section start in one column.
man_examples_even() {
	local m n
	for m in man8/skyd.8 man1/skyctl.1; do
		n=$(man_text 80 "$m" | sed -n '/^EXAMPLES/,/^[A-Z]/p' | sed '1d;$d' | grep . |
			sed 's/[^ ].*//' | sort -u | wc -l)
		[ "$n" -eq 1 ] || { echo "$m: EXAMPLES in $n columns"; return 1; }
	done
}
# The programs' RUNPATH leads to DESTDIR's libsky, without LD_LIBRARY_PATH.
runpath_finds_libsky() {
	local p found
	for p in skyctl skyrender; do
		readelf -d "$dest$BINDIR/$p" | grep -qF "[$RUNPATH]" || { echo "$p: no RUNPATH $RUNPATH"; return 1; }
		found=$(env -u LD_LIBRARY_PATH ldd "$dest$BINDIR/$p" | sed -n 's/^\s*libsky.so.0 => \(\S*\).*/\1/p')
		[ -n "$found" ] && [ "$(realpath "$found")" = "$(realpath "$dest$LIBDIR/libsky.so.0")" ] ||
			{ echo "$p finds libsky.so.0 at '$found', not in $dest$LIBDIR"; return 1; }
	done
}

tmp=$(mktemp -d "${TMPDIR:-/tmp}/skyd-install.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
dest=$tmp/dest
DESTDIR=$dest cmake --install "$build" >"$tmp/install.log" 2>&1
check "cmake --install exits 0" "[ $? -eq 0 ]"

# Every file, by path; the man pages only when scdoc made them.
expected=$tmp/expected
{
	echo "$BINDIR/skyd"
	echo "$BINDIR/skyctl"
	echo "$BINDIR/skyrender"
	echo "$LIBDIR/libsky.so"
	echo "$LIBDIR/libsky.so.0"
	echo "$LIBDIR/libsky.so.0.3.0"
	for h in sky.h skyproto.h skymap.h skysample.h skycloud.h skycloudmarch.h; do echo "$INCLUDEDIR/$h"; done
	for g in sky.glsl skymap.glsl skycloud.glsl skycloud_march.glsl; do echo "$INCLUDEDIR/sky/glsl/$g"; done
	echo "$LIBDIR/pkgconfig/libsky.pc"
	for f in skyConfig.cmake skyConfigVersion.cmake skyTargets.cmake; do
		echo "$LIBDIR/cmake/sky/$f"
	done
	echo "$UNITDIR/skyd.service"
	echo "$UNITDIR/skyd.socket"
	echo "$SYSUSERSDIR/skyd.conf"
	echo "$TMPFILESDIR/skyd.conf"
	echo "$UDEVRULESDIR/70-skyd-sensor.rules"
	echo "$SYSCONFDIR/skyd/skyd.conf"
	for d in README.md PROTOCOL.md clock.md physics.md sensor.md sync.md weather.md clouds.md terrain.md render-clients.md render-client-example.md examples/skyd.conf; do
		echo "$DOCDIR/$d"
	done
	# The Python package, where python/CMakeLists.txt put it.
	[ -f "$build/python/install-files.txt" ] && cat "$build/python/install-files.txt"
	if [ -f "$build/man/skyd.8" ]; then
		echo "$MANDIR/man8/skyd.8"
		echo "$MANDIR/man1/skyctl.1"
		echo "$MANDIR/man5/skyd.conf.5"
		echo "$MANDIR/man3/libsky.3"
	fi
} | sort >"$expected"
# skyTargets-<config>.cmake is named after the build type.
(cd "$dest" && find . \( -type f -o -type l \) | sed 's|^\.||' |
	grep -v "^$LIBDIR/cmake/sky/skyTargets-.*\.cmake\$" | sort) >"$tmp/found"
check "exactly the expected files" "diff -u '$expected' '$tmp/found'"
check "one skyTargets-<config>.cmake" \
	"[ \$(ls '$dest$LIBDIR/cmake/sky/' | grep -c '^skyTargets-') -eq 1 ]"
[ -f "$build/man/skyd.8" ] || echo "note: scdoc is missing, the man pages were not built"

check "skyd and skyctl are executable" "[ -x '$dest$BINDIR/skyd' ] && [ -x '$dest$BINDIR/skyctl' ]"
check "libsky.so -> libsky.so.0 -> libsky.so.0.3.0" \
	"[ \"\$(readlink '$dest$LIBDIR/libsky.so')\" = libsky.so.0 ] &&
	 [ \"\$(readlink '$dest$LIBDIR/libsky.so.0')\" = libsky.so.0.3.0 ]"
check "SONAME libsky.so.0" \
	"readelf -d '$dest$LIBDIR/libsky.so.0.3.0' | grep -q 'SONAME.*\[libsky.so.0\]'"
check "libsky exports only sky_ functions" \
	"! readelf --dyn-syms -W '$dest$LIBDIR/libsky.so.0.3.0' |
	   awk '\$5 == \"GLOBAL\" && \$7 != \"UND\" { print \$8 }' | grep -v '^sky_'"
check "the units name the installed skyd" \
	"grep -q '^ExecStart=$BINDIR/skyd --config $SYSCONFDIR/skyd/skyd.conf\$' '$dest$UNITDIR/skyd.service'"
check "the example config names where it lies" \
	"grep -q -- '--config $SYSCONFDIR/skyd/skyd.conf' '$dest$SYSCONFDIR/skyd/skyd.conf'"
if [ -n "${RUNPATH:-}" ]; then
	check "skyctl and skyrender find DESTDIR's libsky by their RUNPATH" runpath_finds_libsky
else
	check "skyctl and skyrender carry no RUNPATH (libsky in a system directory)" \
		"! readelf -d '$dest$BINDIR/skyctl' '$dest$BINDIR/skyrender' | grep -q 'R.*PATH'"
fi
check "the installed skyd accepts the example config" \
	"'$dest$BINDIR/skyd' -n --config '$dest$SYSCONFDIR/skyd/skyd.conf' >/dev/null"

for h in sky.h skyproto.h skymap.h skysample.h skycloud.h skycloudmarch.h; do
	echo "#include <$h>" >"$tmp/h.c"
	check "$h compiles alone" \
		"cc -std=c17 -Wall -Wextra -Werror -c -I'$dest$INCLUDEDIR' '$tmp/h.c' -o '$tmp/h.o'"
done
if [ -f "$build/man/skyd.8" ] && ! command -v man >/dev/null; then
	echo "note: man is missing: the man pages are not rendered"
elif [ -f "$build/man/skyd.8" ]; then
	for m in man8/skyd.8 man1/skyctl.1 man5/skyd.conf.5 man3/libsky.3; do
		check "$m renders without warnings" \
			"[ -z \"\$(LC_ALL=C.UTF-8 MANWIDTH=80 man --warnings -l '$dest$MANDIR/$m' 2>&1 >/dev/null)\" ]"
	done
	check "skyd(8) names the configured paths" man_names_paths
	check "the pages name no path of another prefix" man_no_other_prefix
	check "the EXAMPLES of skyd(8) and skyctl(1) share one indentation" man_examples_even
	check "skyctl(1) shows --size WxH, no scdoc markup in it" \
		"man_text 200 man1/skyctl.1 | grep -qF -- '[--size WxH]'"
	check "skyd.conf(5) lists every key of skyd --list-keys" \
		"'$dest$BINDIR/skyd' --list-keys | cut -f1 | while read -r k; do
		   MANWIDTH=200 man -l '$dest$MANDIR/man5/skyd.conf.5' 2>/dev/null | grep -qw -- \"\$k\" || exit 1; done"
fi

# The tiny client: the version, a header-only mapping, one request.
cat >"$tmp/tiny.c" <<'EOF'
#include <stdio.h>
#include <stdlib.h>

#include <sky.h>
#include <skysample.h>

int main(void)
{
	sky_client *c;
	sky_reply *r = NULL;
	const char *path = getenv("SKYD_TEST_SOCKET");

	if (sky_version() != SKY_VERSION)
		return 10;
	if (sky_connect(path, &c) < 0)
		return 11;
	if (sky_request(c, "set sun_elevation_deg=7.5", NULL) != 0)
		return 12;
	if (sky_request(c, "get sun_elevation_deg", &r) != 0)
		return 13;
	printf("sun_elevation_deg=%s\n", sky_reply_get(r, "sun_elevation_deg"));
	sky_reply_free(r);
	sky_disconnect(c);
	return 0;
}
EOF
export PKG_CONFIG_PATH=$dest$LIBDIR/pkgconfig
check "pkg-config's libsky points into DESTDIR (relocatable)" \
	"[ \"\$(cd \"\$(pkg-config --variable=includedir libsky)\" && pwd -P)\" = \"\$(cd '$dest$INCLUDEDIR' && pwd -P)\" ] &&
	 [ \"\$(cd \"\$(pkg-config --variable=libdir libsky)\" && pwd -P)\" = \"\$(cd '$dest$LIBDIR' && pwd -P)\" ]"
check "tiny client builds through pkg-config" \
	"cc -std=c17 -Wall -Werror '$tmp/tiny.c' -o '$tmp/tiny-pc' \$(pkg-config --cflags --libs libsky)"
check "tiny client (pkg-config) links DESTDIR's libsky" \
	"LD_LIBRARY_PATH='$dest$LIBDIR' ldd '$tmp/tiny-pc' | grep -q '$dest$LIBDIR/libsky.so.0'"

mkdir -p "$tmp/cm"
cat >"$tmp/cm/CMakeLists.txt" <<EOF
cmake_minimum_required(VERSION 3.25)
project(tiny LANGUAGES C)
find_package(sky 0.1 REQUIRED)
add_executable(tiny-cmake $tmp/tiny.c)
target_link_libraries(tiny-cmake PRIVATE skyd::sky)
EOF
check "tiny client builds through find_package(sky)" \
	"cmake -S '$tmp/cm' -B '$tmp/cm/build' -DCMAKE_PREFIX_PATH='$dest$PREFIX' >'$tmp/cm.log' 2>&1 &&
	 cmake --build '$tmp/cm/build' >>'$tmp/cm.log' 2>&1 || { cat '$tmp/cm.log'; false; }"

# Both run against the installed skyd.
for t in tiny-pc cm/build/tiny-cmake; do
	LD_LIBRARY_PATH=$dest$LIBDIR "$with_skyd" with "$dest$BINDIR/skyd" "$tmp/$t" >"$tmp/run.out" 2>&1
	rc=$?
	if [ $rc -eq 77 ]; then
		echo "skipped: no Vulkan device for the installed skyd"
		exit 77
	fi
	check "$t talks to the installed skyd" \
		"[ $rc -eq 0 ] && grep -qx 'sun_elevation_deg=7.5' '$tmp/run.out' || { cat '$tmp/run.out'; false; }"
done
LD_LIBRARY_PATH=$dest$LIBDIR "$with_skyd" with "$dest$BINDIR/skyd" sh -c \
	"'$dest$BINDIR/skyctl' --socket \"\$SKYD_TEST_SOCKET\" get sun_elevation_deg" >"$tmp/run.out" 2>&1
check "the installed skyctl talks to the installed skyd" \
	"grep -q '^sun_elevation_deg: ' '$tmp/run.out' || { cat '$tmp/run.out'; false; }"

[ $fail -eq 0 ] && echo "test_install: all passed"
exit $fail
