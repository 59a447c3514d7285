#!/usr/bin/env bash
# test_units_sandbox.sh - skyd under what skyd.service confines it to, where
# systemd itself cannot run it: a /proc with only its own pid
# (ProtectProc=invisible, ProcSubset=pid), traced by strace while a client
# subscribes, samples and starts the light sensor (libusb, netlink
# hot-plug). Every system call it made must pass the unit's
# SystemCallFilter= (its allow list less its deny list, as systemd-analyze
# expands them), every device it opened must be one
# DeviceAllow= grants, and it must write no file outside its cache.
#   usage: test_units_sandbox.sh UNIT_FILE WITH_SKYD SKYD SKYCTL
set -u
unit=$1 with_skyd=$2 skyd=$3 skyctl=$4
fail=0
check() { if eval "$2"; then echo "ok: $1"; else echo "FAIL: $1"; fail=1; fi; }

if [ "${1:-}" = "--wrap" ]; then
	# The wrapper test_units_notify runs as skyd: $2 the trace, $3 skyd.
	log=$2 bin=$3
	shift 3
	mount -t proc -o subset=pid,hidepid=invisible proc /proc || exit 90
	exec strace -f -qq -o "$log" "$bin" "$@"
fi

for tool in strace unshare systemd-analyze; do
	command -v "$tool" >/dev/null || { echo "skipped: $tool is missing"; exit 77; }
done
# A pid namespace of its own, so that a /proc of its own can be mounted.
ns=
for try in "unshare -mpf --propagation private" "unshare -rmpf --propagation private"; do
	if $try true 2>/dev/null; then ns=$try; break; fi
done
[ -n "$ns" ] || { echo "skipped: no mount and pid namespace (unshare refused)"; exit 77; }
strace -f -qq -o /dev/null true 2>/dev/null || { echo "skipped: strace cannot trace here"; exit 77; }

tmp=$(mktemp -d "${TMPDIR:-/tmp}/skyd-sandbox.XXXXXX")
[ -n "${SKYD_TEST_KEEP:-}" ] || trap 'rm -rf "$tmp"' EXIT
self=$(cd "$(dirname "$0")" && pwd)/$(basename "$0")
cat >"$tmp/skyd" <<EOF
#!/bin/sh
exec $ns "$self" --wrap "$tmp/trace" "$skyd" "\$@"
EOF
chmod +x "$tmp/skyd"
mkdir "$tmp/cache"
cat >"$tmp/client" <<EOF
#!/bin/sh
set -e
c="$skyctl --socket \$SKYD_TEST_SOCKET"
\$c subscribe tables=all >/dev/null
\$c set sun_elevation_deg=4 >/dev/null
\$c sample sky el_deg=10 az_deg=180 >/dev/null
\$c set sensor_mode=cloud >/dev/null
\$c get sensor >/dev/null
\$c status >"$tmp/status"
EOF
chmod +x "$tmp/client"

MESA_SHADER_CACHE_DIR=$tmp/cache XDG_CACHE_HOME=$tmp/cache \
	"$with_skyd" with "$tmp/skyd" "$tmp/client" >"$tmp/run.out" 2>&1
rc=$?
if [ $rc -eq 77 ]; then echo "skipped: no Vulkan device"; exit 77; fi
check "skyd served the client under the sandbox" "[ $rc -eq 0 ] || { cat '$tmp/run.out'; false; }"
check "the trace was written" "[ -s '$tmp/trace' ]"
check "it ran to a clean stop" "grep -q '^[0-9]* *exit_group(0)' '$tmp/trace'"

# The filter the unit sets, expanded as systemd expands it.
expand() {
	systemd-analyze syscall-filter "$1" | sed -n 's/^    \([^# ].*\)$/\1/p' | while read -r s; do
		case $s in @*) expand "$s" ;; *) echo "$s" ;; esac
	done
}
allow=$(grep -o '^SystemCallFilter=@[a-z-]*$' "$unit" | cut -d= -f2)
deny=$(sed -n 's/^SystemCallFilter=~//p' "$unit")
check "the unit sets an allow list and a deny list" "[ -n '$allow' ] && [ -n '$deny' ]"
expand "$allow" | sort -u >"$tmp/allowed"
for g in $deny; do expand "$g"; done | sort -u >"$tmp/denied"
comm -23 "$tmp/allowed" "$tmp/denied" >"$tmp/permitted"
sed -n 's/^[0-9]\+ \+\([a-z0-9_]\+\)(.*/\1/p' "$tmp/trace" | sort -u >"$tmp/used"
echo "system calls used: $(wc -l <"$tmp/used"), permitted by the unit: $(wc -l <"$tmp/permitted")"
comm -23 "$tmp/used" "$tmp/permitted" >"$tmp/outside"
check "every system call skyd made passes SystemCallFilter=" \
	"[ ! -s '$tmp/outside' ] || { echo 'outside the filter:'; cat '$tmp/outside'; false; }"

# Devices: the pseudo devices of DevicePolicy=closed, render nodes, USB.
grep -o 'open[a-z]*([^"]*"/dev/[^"]*"[^)]*) = [0-9]' "$tmp/trace" | grep -o '"/dev/[^"]*"' |
	tr -d '"' | sort -u >"$tmp/devs"
check "only devices DeviceAllow= grants were opened" \
	"! grep -Ev '^/dev/(null|zero|full|random|urandom|tty|ptmx|dri/.*|bus/usb/.*)\$' '$tmp/devs'"
# Writes: nothing but the cache (ProtectSystem=strict, CacheDirectory=).
grep -E 'open[a-z]*\(.*(O_WRONLY|O_RDWR|O_CREAT).*\) = [0-9]' "$tmp/trace" |
	grep -o '"/[^"]*"' | tr -d '"' | sort -u >"$tmp/writes"
check "no file written outside the cache and /dev" \
	"! grep -Ev '^($tmp/cache/|/dev/)' '$tmp/writes'"
# What the unit's comment claims: lavapipe's JIT makes memory executable
# at run time, which MemoryDenyWriteExecute= would refuse (the loader maps
# libraries executable with mmap, never with mprotect).
jit=$(grep -cE '^[0-9]+ +mprotect\(.*PROT_EXEC' "$tmp/trace")
echo "memory made executable at run time (mprotect PROT_EXEC): $jit"
echo "/proc paths tried: $(grep -o '"/proc/[^"]*"' "$tmp/trace" | sed 's|/proc/[0-9]*/|/proc/PID/|' | sort -u | tr '\n' ' ')"

[ $fail -eq 0 ] && echo "test_units_sandbox: all passed"
exit $fail
