#!/usr/bin/env bash
# test_install_prefix.sh - the install checks for a prefix other than the
# one the suite's build folder was configured with: configures a build
# folder of this source with -DCMAKE_INSTALL_PREFIX=PREFIX, builds what
# installs (skyd, skyctl, skyrender, libsky, the man pages), then runs
# test_install.sh (cmake --install into a DESTDIR, file by file) and
# test_units_verify.sh on it. Skipped (77) only when both are.
#   usage: test_install_prefix.sh PREFIX SOURCE_DIR WITH_SKYD
set -u
prefix=$1 src=$2 with_skyd=$3
here=$(cd "$(dirname "$0")" && pwd)
tmp=$(mktemp -d "${TMPDIR:-/tmp}/skyd-prefix.XXXXXX")
trap 'rm -rf "$tmp"' EXIT

# The man pages where scdoc is there (the build goes on without them).
man=
command -v scdoc >/dev/null && man=man
echo "configuring and building for --prefix $prefix in $tmp/build"
if ! { cmake -S "$src" -B "$tmp/build" -DCMAKE_INSTALL_PREFIX="$prefix" -DBUILD_TESTING=OFF &&
	cmake --build "$tmp/build" -j "$(nproc)" --target skyd skyctl skyrender sky $man; } \
	>"$tmp/build.log" 2>&1; then
	tail -n 40 "$tmp/build.log"
	echo "FAIL: the build for --prefix $prefix"
	exit 1
fi
"$here/test_install.sh" "$tmp/build" "$with_skyd"
a=$?
"$here/test_units_verify.sh" "$tmp/build"
b=$?
echo "--prefix $prefix: test_install.sh exit $a, test_units_verify.sh exit $b"
[ $a -eq 77 ] && [ $b -eq 77 ] && exit 77
[ $a -eq 0 -o $a -eq 77 ] && [ $b -eq 0 -o $b -eq 77 ] && exit 0
exit 1
