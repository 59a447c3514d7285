/* umockdev_exec.h - runs a test again under umockdev-run with mocked USB
 * devices and their replayed captures (tests/sensor: gen.py writes them). */
#ifndef SKYD_UMOCKDEV_EXEC_H
#define SKYD_UMOCKDEV_EXEC_H

#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

/* The sysfs parent of the mocked devices: bus 1 of one host controller. */
#define UMOCKDEV_SYSFS "/sys/devices/pci0000:00/0000:00:14.0/usb1/1-"

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
	execvp(argv[0], argv);
	printf("%s: umockdev-run: %s: skipped\n", name, strerror(errno));
	return 77;
}

#endif
