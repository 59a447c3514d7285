/* fuzz_sync.c - libFuzzer target for the replication messages as a
 * follower reads them off the broker (sync/sync_msg.c): the input is one
 * payload, decoded as a state message and as the controller's presence. A
 * state the decoder accepts must encode again, and that message must be
 * accepted too: a follower never holds a state that it could not send on
 * when it takes over as controller. Built without libFuzzer, a main()
 * replays the files named on the command line (fuzz_replay.h). */
#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "state.h"
#include "sync.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	static char again[SYNC_MSG_MAX + 1];
	struct sync_msg_header h, h2;
	struct sync_presence p;
	struct sky_state *s = malloc(sizeof(*s)), *s2 = malloc(sizeof(*s2));
	char why[256];
	size_t len = 0;

	if (!s || !s2)
		abort();
	/* The payload exactly as the broker hands it: not terminated. */
	uint8_t *payload = malloc(size ? size : 1);
	if (!payload)
		abort();
	memcpy(payload, data, size);
	if (sync_msg_decode(payload, size, &h, s, why, sizeof(why)) == SYNC_DROP_NONE) {
		int r = sync_msg_encode(s, &h, again, sizeof(again), &len);
		/* -ERANGE: the clock, anchored at an apply time long past,
		 * shows a year outside 0..9999 now; nothing else may fail. */
		if (r < 0 && r != -ERANGE) {
			fprintf(stderr, "fuzz_sync: an accepted state does not encode: %s\n",
				strerror(-r));
			abort();
		}
		enum sync_drop d = r == 0 ? sync_msg_decode(again, len, &h2, s2, why, sizeof(why))
					  : SYNC_DROP_NONE;
		if (d != SYNC_DROP_NONE) {
			fprintf(stderr, "fuzz_sync: a state encoded from an accepted one is dropped "
				"(%s): %s\n", sync_drop_name(d), why);
			abort();
		}
	}
	sync_presence_decode(payload, size, &p, why, sizeof(why));
	free(payload);
	free(s);
	free(s2);
	return 0;
}

#include "fuzz_replay.h"
