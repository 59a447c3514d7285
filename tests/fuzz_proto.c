/* fuzz_proto.c - libFuzzer target for the control protocol's parser and
 * request handling: every line of the input is parsed as a request, and a
 * set is applied to a copy of the state and validated as skyd does; every
 * line is also parsed as a reply, as libsky and skyctl do. Built without
 * libFuzzer, a main() replays the files named on the command line. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proto.h"
#include "state.h"

static void one_line(char *line, const struct sky_state *base)
{
	char copy[SKY_PROTO_LINE_MAX + 1], err[256];
	struct proto_request req;
	struct proto_reply rep;
	struct proto_arg args[16];

	snprintf(copy, sizeof(copy), "%s", line);
	if (proto_parse_request(copy, &req, err, sizeof(err)) == 0) {
		if (!strcmp(req.verb, "set")) {
			struct sky_state s = *base;
			uint32_t dirty = 0;
			for (int i = 0; i < req.n_args; i++)
				if (!req.args[i].value ||
				    state_set(&s, req.args[i].key, req.args[i].value, &dirty, err, sizeof(err)) < 0)
					return;
			state_validate(&s, 0, err, sizeof(err));
		} else if (!strcmp(req.verb, "get")) {
			char buf[256];
			for (int i = 0; i < req.n_args; i++)
				state_get(base, req.args[i].key, buf, sizeof(buf));
		} else if (!strcmp(req.verb, "subscribe") && req.n_args) {
			uint32_t mask;
			const char *t = proto_arg_value(req.args, req.n_args, "tables");
			if (t)
				state_parse_tables(t, &mask);
		}
	}
	snprintf(copy, sizeof(copy), "%s", line);
	if (proto_parse_reply(copy, &rep) == 0 && rep.kind == PROTO_EVENT) {
		char v[SKY_PROTO_LINE_MAX + 1];
		snprintf(v, sizeof(v), "%s", rep.value);
		proto_split_args(v, args, 16);
	}
	char ack[SKY_PROTO_LINE_MAX + 64];
	proto_format_ack(ack, sizeof(ack), SKY_ACK_SYNTAX, "x", line);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	static struct sky_state base;
	static int ready;
	char line[SKY_PROTO_LINE_MAX + 1];
	size_t n = 0;

	if (!ready) {
		state_default(&base);
		ready = 1;
	}
	/* Lines as skyd frames them: at most SKY_PROTO_LINE_MAX bytes, NULs
	 * end the C string early just as they would in skyd. */
	for (size_t i = 0; i <= size; i++) {
		if (i == size || data[i] == '\n' || n == SKY_PROTO_LINE_MAX) {
			line[n] = 0;
			one_line(line, &base);
			n = 0;
			continue;
		}
		line[n++] = (char)data[i];
	}
	return 0;
}

#ifdef SKYD_FUZZ_REPLAY
int main(int argc, char **argv)
{
	static uint8_t buf[1 << 20];

	for (int i = 1; i < argc; i++) {
		FILE *f = fopen(argv[i], "rb");
		if (!f) {
			perror(argv[i]);
			return 1;
		}
		size_t n = fread(buf, 1, sizeof(buf), f);
		fclose(f);
		LLVMFuzzerTestOneInput(buf, n);
	}
	printf("fuzz_proto: replayed %d inputs\n", argc - 1);
	return 0;
}
#endif
