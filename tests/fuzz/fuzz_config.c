/* fuzz_config.c - libFuzzer target for the configuration file reader
 * (state/config.c) as skyd reads /etc/skyd/skyd.conf at start and on
 * SIGHUP: the input is the file, read through a memfd. The daemon's own
 * keys (sync*, controllers, max_*) are taken by a stand-in of skyd's
 * callback, which refuses an empty value as skyd's do; every other key
 * goes to the state, which must come out whole and valid, or untouched.
 * Built without libFuzzer, a main() replays the files named on the
 * command line (fuzz_replay.h). */
#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "config.h"
#include "state.h"

static int daemon_key(void *ctx, const char *key, const char *value, char *err, size_t err_size)
{
	static const char *const prefixes[] = { "sync", "controllers", "max_" };

	for (size_t i = 0; i < sizeof(prefixes) / sizeof(prefixes[0]); i++) {
		if (strncmp(key, prefixes[i], strlen(prefixes[i])) != 0)
			continue;
		if (!*value) {
			snprintf(err, err_size, "%s: a value expected", key);
			return -EINVAL;
		}
		(*(unsigned *)ctx)++;
		return 1;
	}
	return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	static struct sky_state base;
	static int ready;
	char path[64], err[512];
	unsigned taken = 0;

	if (!ready) {
		state_default(&base);
		ready = 1;
	}
	int fd = memfd_create("fuzz_config", MFD_CLOEXEC);
	if (fd < 0 || write(fd, data, size) != (ssize_t)size)
		abort();
	snprintf(path, sizeof(path), "/proc/self/fd/%d", fd);
	struct sky_state *s = malloc(sizeof(*s));
	if (!s)
		abort();
	*s = base;
	int r = config_load_with(path, s, daemon_key, &taken, err, sizeof(err));
	if (r == 0 && state_validate(s, 0, err, sizeof(err)) < 0) {
		fprintf(stderr, "fuzz_config: a file taken leaves an invalid state: %s\n", err);
		abort();
	}
	if (r < 0 && memcmp(s, &base, sizeof(*s)) != 0) {
		fprintf(stderr, "fuzz_config: a file refused changed the state: %s\n", err);
		abort();
	}
	free(s);
	close(fd);
	return 0;
}

#include "fuzz_replay.h"
