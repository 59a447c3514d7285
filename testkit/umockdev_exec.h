/* umockdev_exec.h - runs a test again under umockdev-run with mocked USB
 * devices and their replayed captures (tests/sensor: gen.py writes them). */
#ifndef SKYD_UMOCKDEV_EXEC_H
#define SKYD_UMOCKDEV_EXEC_H

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* The sysfs parent of the mocked devices: bus 1 of one host controller. */
#define UMOCKDEV_SYSFS "/sys/devices/pci0000:00/0000:00:14.0/usb1/1-"

/* In a sanitizer's options (NAME=a=1:log_path=/dir/asan:b=2), log_path's
 * directory, and the options with log_path made the bare file name; 0, or
 * -1 when there is no log_path with a directory. */
static inline int umockdev_log_path_bare(const char *name, char *dir, size_t dir_size,
					 char *opts, size_t opts_size)
{
	const char *o = getenv(name), *lp = o ? strstr(o, "log_path=") : NULL;

	if (!lp)
		return -1;
	lp += 9;
	size_t n = strcspn(lp, ":");
	const char *slash = memrchr(lp, '/', n);
	if (!slash || slash == lp)
		return -1;
	snprintf(dir, dir_size, "%.*s", (int)(slash - lp), lp);
	snprintf(opts, opts_size, "%.*s%s", (int)(lp - o), o, slash + 1);
	return 0;
}

/* Under the sanitizers (tests/CMakeLists.txt sets their options), what
 * umockdev-run and umockdev-wrapper start needs two things. Their library
 * is preloaded ahead of AddressSanitizer's runtime, which refuses to start
 * unless told that the order is meant. And a sanitizer makes its log_path's
 * directory when it starts, before the preloaded library is ready, through
 * that library's mkdir, which then crashes: the directory becomes the
 * working directory and log_path the bare file name, which needs no mkdir.
 * Does nothing in a build without the sanitizers. */
static inline void umockdev_allow_preload(void)
{
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
	static const char *const names[] = { "ASAN_OPTIONS", "UBSAN_OPTIONS", "TSAN_OPTIONS" };
	char dir[512], opts[1024], buf[1100];

	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++)
		if (umockdev_log_path_bare(names[i], dir, sizeof(dir), opts, sizeof(opts)) == 0 &&
		    chdir(dir) == 0)
			setenv(names[i], opts, 1);
	const char *o = getenv("ASAN_OPTIONS");
	if (!o || !strstr(o, "verify_asan_link_order=")) {
		snprintf(buf, sizeof(buf), "%s%sverify_asan_link_order=0", o ? o : "",
			 o && *o ? ":" : "");
		setenv("ASAN_OPTIONS", buf, 1);
	}
#endif
}

/* Replaces the process with `umockdev-run -d DIR/DEV.umockdev ... -p
 * SYSFS<port>=DIR/CAP.pcap ... -- self arg`. devices: up to 4 names,
 * NULL-terminated or full; captures: up to 4 "port=name" pairs, likewise.
 * Returns 77 (skipped) only when umockdev-run cannot be started; the
 * caller returns it from main. */
static inline int umockdev_exec(const char *dir, const char *const devices[4],
				const char *const captures[4], char *self, const char *arg,
				const char *name)
{
	static char args[8][512];
	char *argv[24];
	int n = 0, a = 0;

	argv[n++] = "umockdev-run";
	for (int i = 0; i < 4 && devices[i]; i++, a++) {
		snprintf(args[a], sizeof(args[a]), "%s/%s.umockdev", dir, devices[i]);
		argv[n++] = "-d";
		argv[n++] = args[a];
	}
	for (int i = 0; i < 4 && captures[i]; i++, a++) {
		const char *eq = strchr(captures[i], '=');
		snprintf(args[a], sizeof(args[a]), UMOCKDEV_SYSFS "%.*s=%s/%s.pcap",
			 (int)(eq - captures[i]), captures[i], dir, eq + 1);
		argv[n++] = "-p";
		argv[n++] = args[a];
	}
	argv[n++] = "--";
	argv[n++] = self;
	argv[n++] = (char *)arg;
	argv[n] = NULL;
	umockdev_allow_preload();
	execvp(argv[0], argv);
	printf("%s: umockdev-run: %s: skipped\n", name, strerror(errno));
	return 77;
}

#endif
