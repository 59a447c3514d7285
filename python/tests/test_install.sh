#!/usr/bin/env bash
# test_install.sh - the Python package as `cmake --install` lays it out in a
# DESTDIR (exactly the files python/CMakeLists.txt lists, importable from
# there, its manual readable with help()), and as Debian's pip builds its
# wheel, offline.
#   usage: test_install.sh BUILD_DIR PYTHON SOURCE_DIR
set -u
build=$1
py=$2
src=$3
fail=0
check() { if eval "$2"; then echo "ok: $1"; else echo "FAIL: $1"; fail=1; fi; }

"$py" -c 'import numpy' 2>/dev/null || { echo "skipped: $py lacks numpy"; exit 77; }
command -v cmake >/dev/null || { echo "skipped: cmake is missing"; exit 77; }
tmp=$(mktemp -d "${TMPDIR:-/tmp}/skyd-pyinstall.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
dest=$tmp/dest
export PYTHONDONTWRITEBYTECODE=1

DESTDIR=$dest cmake --install "$build" --component python >"$tmp/install.log" 2>&1
check "cmake --install --component python exits 0" "[ $? -eq 0 ] || { cat '$tmp/install.log'; false; }"
sort "$build/python/install-files.txt" >"$tmp/expected"
(cd "$dest" && find . -type f | sed 's|^\.||' | sort) >"$tmp/found"
check "exactly the package's files" "diff -u '$tmp/expected' '$tmp/found'"

pkg=$(dirname "$(head -n 1 "$build/python/install-files.txt")")
site=$dest$(dirname "$pkg")
check "skyd imports from the installed files" \
	"(cd '$tmp' && PYTHONPATH='$site' '$py' -c 'import skyd, sys; assert skyd.__file__ == sys.argv[1], skyd.__file__' '$dest$pkg/__init__.py')"
check "the installed package goes where the interpreter looks (prefix /usr, /usr/local)" \
	"'$py' -c 'import sys, sysconfig; p = sys.argv[1]; paths = set(sys.path) | {sysconfig.get_path(\"purelib\")}; sys.exit(0 if not p.startswith((\"/usr/lib\", \"/usr/local/lib\")) or p in paths else 1)' '$(dirname "$pkg")'"
check "help(skyd) reads as a manual" \
	"(cd '$tmp' && PYTHONPATH='$site' '$py' -c '
import pydoc, skyd
text = pydoc.render_doc(skyd, renderer=pydoc.plaintext)
for part in (\"CONNECTING\", \"CHANGING THE SKY\", \"ERRORS\", \"THE TABLES AS ARRAYS\", \"SAMPLING\",
             \"ASYNCIO\", \"class Client\", \"class AsyncClient\", \"class SkyError\", \"class Snapshot\"):
    assert part in text, part
')"

if "$py" -m pip --version >/dev/null 2>&1; then
	mkdir -p "$tmp/wheel-src"
	cp -r "$src/skyd" "$src/pyproject.toml" "$tmp/wheel-src/"
	(cd "$tmp/wheel-src" && "$py" -m pip wheel --no-deps --no-build-isolation --no-index \
		-w "$tmp/wheels" .) >"$tmp/wheel.log" 2>&1
	check "pip wheel builds the package offline" \
		"ls '$tmp/wheels'/skyd-*-py3-none-any.whl >/dev/null 2>&1 || { cat '$tmp/wheel.log'; false; }"
	check "the wheel holds every module the install does" \
		"'$py' -c 'import glob, os, sys, zipfile
names = set(zipfile.ZipFile(glob.glob(sys.argv[1] + \"/*.whl\")[0]).namelist())
want = {\"skyd/\" + os.path.basename(l.strip()) for l in open(sys.argv[2]) if l.strip()}
sys.exit(0 if want <= names else 1)' '$tmp/wheels' '$build/python/install-files.txt'"
else
	echo "note: $py has no pip (python3-pip): the wheel is not built"
fi

[ $fail -eq 0 ] && echo "test_install (python): all passed"
exit $fail
