#!/usr/bin/env bash
# test_units_verify.sh - the installed units as systemd's own tools judge
# them: `systemd-analyze verify` prints nothing at all (it exits 0 on some
# warnings, so any output fails), and `systemd-analyze security
# --offline=true` rates skyd.service at or under 2.5.
#   usage: test_units_verify.sh BUILD_DIR
# PREFIX, UNITDIR and TMPFILESDIR come from BUILD_DIR/install-dirs.env.
#
# verify checks that each Exec path is executable and each man: page is
# found, on the host: it runs in a private mount namespace where the DESTDIR
# install lies over PREFIX (an overlay of the two, read-only), so that it
# sees the installed files at the paths the units name and the host's own
# beside them: with PREFIX /usr, systemd-analyze and man themselves.
set -u
build=$1
. "$build/install-dirs.env"
max_exposure=2.5
fail=0
check() { if eval "$2"; then echo "ok: $1"; else echo "FAIL: $1"; fail=1; fi; }

command -v systemd-analyze >/dev/null || { echo "skipped: systemd-analyze is missing"; exit 77; }
command -v unshare >/dev/null || { echo "skipped: unshare is missing"; exit 77; }
tmp=$(mktemp -d "${TMPDIR:-/tmp}/skyd-units.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
dest=$tmp/dest
DESTDIR=$dest cmake --install "$build" >"$tmp/install.log" 2>&1 ||
	{ cat "$tmp/install.log"; echo "FAIL: cmake --install"; exit 1; }
service=$dest$UNITDIR/skyd.service
socket=$dest$UNITDIR/skyd.socket

# Root, or an unprivileged user namespace, may bind-mount in its own
# mount namespace; without either the check cannot run here.
ns=
for try in "unshare -m --propagation private" "unshare -rm --propagation private"; do
	if $try true 2>/dev/null; then ns=$try; break; fi
done
[ -n "$ns" ] || { echo "skipped: no mount namespace (unshare -m / -rm refused)"; exit 77; }
[ -d "$PREFIX" ] || { echo "skipped: $PREFIX does not exist to mount over"; exit 77; }
# The overlay where the kernel allows it (as root, or unprivileged since
# Linux 5.11); else a bind mount, which hides what PREFIX held: only where
# that is not systemd-analyze's and man's own directory.
mount="mount -t overlay overlay -o lowerdir=\"\$1\":\"\$2\" \"\$2\""
if ! $ns sh -c "$mount" sh "$dest$PREFIX" "$PREFIX" 2>/dev/null; then
	case $(command -v systemd-analyze) in
	"$PREFIX"/*) echo "skipped: no overlay mount, and a bind mount over $PREFIX would hide systemd-analyze"
		exit 77 ;;
	esac
	mount='mount --bind "$1" "$2"'
fi
# The units' man: links need the man pages (scdoc) and man (man-db).
man=yes
if [ ! -f "$build/man/skyd.8" ] || ! command -v man >/dev/null; then
	echo "note: no man pages or no man here: verify runs with --man=no"
	man=no
fi
$ns sh -c "$mount"' && MANPATH="$3" exec systemd-analyze verify --man="$4" "$5" "$6"' \
	sh "$dest$PREFIX" "$PREFIX" "$PREFIX/share/man" "$man" "$UNITDIR/skyd.socket" \
	"$UNITDIR/skyd.service" >"$tmp/verify.out" 2>&1
rc=$?
check "systemd-analyze verify exits 0" "[ $rc -eq 0 ]"
check "systemd-analyze verify prints nothing" "[ ! -s '$tmp/verify.out' ] || { cat '$tmp/verify.out'; false; }"

systemd-analyze security --offline=true "$service" >"$tmp/security.out" 2>&1
exposure=$(sed -n 's/.*Overall exposure level for skyd.service: \([0-9.]*\).*/\1/p' "$tmp/security.out")
echo "exposure: ${exposure:-unreadable} (at most $max_exposure)"
check "the exposure is read" "[ -n '$exposure' ] || { cat '$tmp/security.out'; false; }"
check "exposure $exposure <= $max_exposure" \
	"awk -v e='$exposure' -v m='$max_exposure' 'BEGIN { exit !(e != \"\" && e + 0 <= m + 0) }' ||
	 { grep '✗' '$tmp/security.out'; false; }"

# The socket outlives the service: its directory is nobody's
# RuntimeDirectory=, and tmpfiles makes it.
check "skyd.service has no RuntimeDirectory=" "! grep -q '^RuntimeDirectory' '$service'"
check "skyd.socket listens in /run/skyd" "grep -qx 'ListenStream=/run/skyd/control' '$socket'"
check "tmpfiles makes /run/skyd" "grep -q '^d /run/skyd ' '$dest$TMPFILESDIR/skyd.conf'"
check "the watchdog and reload are set" \
	"grep -q '^WatchdogSec=' '$service' && grep -q '^ExecReload=.*kill -HUP' '$service' &&
	 grep -qx 'Type=notify' '$service' && grep -qx 'Restart=on-failure' '$service'"

[ $fail -eq 0 ] && echo "test_units_verify: all passed"
exit $fail
