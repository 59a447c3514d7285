/* test_skyctl.c - skyctl as a user runs it, against the real skyd on a
 * private socket: every verb, the exit codes 0 / 1 / 2, batch from stdin,
 * watch, dump and render (a PNG of the right size), the timeout from
 * SKYCTL_TIMEOUT_MS. */
#include <poll.h>
#include <sys/stat.h>

#include "daemon_harness.h"
#include "sky.h"
#include "skyproto.h"
#include "test.h"

static const char *const small[] = { HARNESS_SMALL, NULL };
static struct daemon d;

struct run {
	int code;			/* exit status, or -1 if it did not exit */
	char out[65536], err[8192];
};

/* Runs skyctl --socket <ours> args..., feeding input (may be NULL) on stdin. */
static void skyctl(struct run *r, const char *input, const char *const *args)
{
	const char *argv[64];
	int n = 0, in[2], out[2], err[2];
	argv[n++] = SKYCTL_BINARY;
	argv[n++] = "--socket";
	argv[n++] = d.sock;
	for (int i = 0; args[i] && n < 63; i++)
		argv[n++] = args[i];
	argv[n] = NULL;
	memset(r, 0, sizeof(*r));
	r->code = -1;
	if (pipe2(in, O_CLOEXEC) || pipe2(out, O_CLOEXEC) || pipe2(err, O_CLOEXEC))
		return;
	pid_t pid = fork();
	if (pid == 0) {
		dup2(in[0], 0);
		dup2(out[1], 1);
		dup2(err[1], 2);
		execv(argv[0], (char *const *)argv);
		_exit(127);
	}
	close(in[0]);
	close(out[1]);
	close(err[1]);
	if (input)
		(void)!write(in[1], input, strlen(input));
	close(in[1]);
	size_t no = 0, ne = 0;
	struct pollfd p[2] = { { out[0], POLLIN, 0 }, { err[0], POLLIN, 0 } };
	while (p[0].fd >= 0 || p[1].fd >= 0) {
		if (poll(p, 2, HARNESS_TIMEOUT_MS) <= 0)
			break;
		for (int k = 0; k < 2; k++) {
			if (p[k].fd < 0 || !p[k].revents)
				continue;
			char *buf = k ? r->err : r->out;
			size_t *len = k ? &ne : &no, cap = (k ? sizeof(r->err) : sizeof(r->out)) - 1;
			char sink[4096];
			ssize_t got = *len < cap ? read(p[k].fd, buf + *len, cap - *len) :
						   read(p[k].fd, sink, sizeof(sink));
			if (got <= 0) {
				close(p[k].fd);
				p[k].fd = -1;
			} else if (*len < cap) {
				*len += (size_t)got;
			}
		}
	}
	int status;
	waitpid(pid, &status, 0);
	if (WIFEXITED(status))
		r->code = WEXITSTATUS(status);
}

#define RUN(r, input, ...) skyctl(r, input, (const char *const[]){ __VA_ARGS__, NULL })

static void expect(const struct run *r, int code, const char *in_out, const char *what)
{
	if (r->code != code)
		FAIL("%s: exit %d, expected %d; stderr: %s", what, r->code, code, r->err);
	if (in_out && !strstr(r->out, in_out))
		FAIL("%s: stdout lacks '%s': %s", what, in_out, r->out);
}

/* Width and height from a PNG's IHDR; -1 if it is not a PNG. */
static int png_size(const char *path, uint32_t *w, uint32_t *h)
{
	unsigned char b[24];
	FILE *f = fopen(path, "rb");
	if (!f)
		return -1;
	size_t n = fread(b, 1, sizeof(b), f);
	fclose(f);
	if (n < 24 || memcmp(b, "\x89PNG\r\n\x1a\n", 8) || memcmp(b + 12, "IHDR", 4))
		return -1;
	*w = (uint32_t)b[16] << 24 | (uint32_t)b[17] << 16 | (uint32_t)b[18] << 8 | b[19];
	*h = (uint32_t)b[20] << 24 | (uint32_t)b[21] << 16 | (uint32_t)b[22] << 8 | b[23];
	return 0;
}

static void test_verbs(void)
{
	static struct run r;
	RUN(&r, NULL, "ping");
	expect(&r, 0, NULL, "ping");
	RUN(&r, NULL, "set", "sun_elevation_deg=20", "sun_azimuth_deg=200");
	expect(&r, 0, "generation: ", "set");
	RUN(&r, NULL, "get", "sun_elevation_deg");
	expect(&r, 0, "sun_elevation_deg: 20", "get");
	RUN(&r, NULL, "get");
	expect(&r, 0, "altitude_km: ", "get all");
	RUN(&r, NULL, "status");
	expect(&r, 0, "device: ", "status");
	RUN(&r, NULL, "commands");
	expect(&r, 0, "command: sample", "commands");
	RUN(&r, NULL, "help", "set");
	expect(&r, 0, "usage: set", "help set");
	/* help alone: the verbs and where to read on, not help's own usage */
	RUN(&r, NULL, "help");
	expect(&r, 0, "skyd's verbs: set get", "help");
	expect(&r, 0, "skyctl help VERB", "help");
	RUN(&r, NULL, "subscribe", "tables=skyview");
	expect(&r, 0, "slot_bytes: ", "subscribe");
	/* the daemon computes what subscribers want; sample needs the tables */
	RUN(&r, NULL, "sample", "sky", "el_deg=10", "az_deg=180");
	expect(&r, 0, "radiance_rgb_cd_m2: ", "sample sky");
	RUN(&r, NULL, "sample", "sun");
	expect(&r, 0, "illuminance_rgb_lx: ", "sample sun");
	RUN(&r, NULL, "sample", "ambient");
	expect(&r, 0, "illuminance_lx: ", "sample ambient");
	RUN(&r, "# comment\nsun_elevation_deg=15\n\nset sun_azimuth_deg=100 altitude_km=0.5\n", "batch");
	expect(&r, 0, "generation: ", "batch");
	RUN(&r, NULL, "get", "sun_azimuth_deg", "altitude_km");
	expect(&r, 0, "sun_azimuth_deg: 100", "get after batch");
	CHECK(strstr(r.out, "altitude_km: 0.5") != NULL);
	RUN(&r, NULL, "close");
	expect(&r, 0, NULL, "close");

	/* refusals: 1, and the ACK line on stderr */
	RUN(&r, NULL, "set", "sun_elevation_deg=91");
	expect(&r, 1, NULL, "set out of range");
	CHECK(strstr(r.err, "ACK [51]") != NULL);
	RUN(&r, NULL, "set", "no_such_key=1");
	expect(&r, 1, NULL, "set unknown key");
	RUN(&r, NULL, "frobnicate");
	expect(&r, 1, NULL, "unknown verb");
	CHECK(strstr(r.err, "ACK [5]") != NULL);
	RUN(&r, "sun_elevation_deg=10\nsun_elevation_deg=999\n", "batch");
	expect(&r, 1, NULL, "batch with a bad line");
	RUN(&r, NULL, "get", "sun_elevation_deg");
	expect(&r, 0, "sun_elevation_deg: 15", "a refused batch changes nothing");
	RUN(&r, NULL, "sample", "moon");
	expect(&r, 1, NULL, "sample moon");

	/* usage errors and no daemon: 2 */
	RUN(&r, NULL, "set", "novalue");
	expect(&r, 2, NULL, "set without =");
	RUN(&r, NULL, "render", "--view", "cube", "x.png");
	expect(&r, 2, NULL, "render bad view");
	RUN(&r, NULL, "render", "--size", "0x10", "x.png");
	expect(&r, 2, NULL, "render bad size");
	RUN(&r, NULL, "dump");
	expect(&r, 2, NULL, "dump without DIR");
	RUN(&r, NULL, "--bogus-option");
	expect(&r, 2, NULL, "unknown option");
	RUN(&r, NULL, "--help");
	expect(&r, 0, "Exit status", "--help");
	const char *argv[] = { SKYCTL_BINARY, "--socket", "/nonexistent/skyd/control", "ping", NULL };
	pid_t pid = fork();
	if (pid == 0) {
		int null = open("/dev/null", O_WRONLY);
		dup2(null, 2);
		execv(argv[0], (char *const *)argv);
		_exit(127);
	}
	int status;
	waitpid(pid, &status, 0);
	CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 2);
}

/* watch: its first line says it is subscribed; a set then shows up. */
static void test_watch(void)
{
	int out[2];
	CHECK(pipe2(out, O_CLOEXEC) == 0);
	pid_t pid = fork();
	if (pid == 0) {
		dup2(out[1], 1);
		execl(SKYCTL_BINARY, SKYCTL_BINARY, "--socket", d.sock, "watch", "--count", "1", (char *)NULL);
		_exit(127);
	}
	close(out[1]);
	FILE *f = fdopen(out[0], "r");
	char line[256];
	CHECK(fgets(line, sizeof(line), f) && strncmp(line, "watching: generation=", 21) == 0);
	sky_client *c = NULL;
	sky_reply *rep = NULL;
	CHECK(sky_connect(d.sock, &c) == 0);
	CHECK(c && sky_request(c, "set sun_elevation_deg=3", &rep) == 0);
	unsigned long want = rep ? strtoul(sky_reply_get(rep, "generation"), NULL, 10) : 0;
	sky_reply_free(rep);
	sky_disconnect(c);
	unsigned long got = 0;
	while (got < want && fgets(line, sizeof(line), f)) {
		CHECK(strncmp(line, "generation=", 11) == 0);
		got = strtoul(line + 11, NULL, 10);
	}
	/* --count 1: it exits after the first change it saw */
	int status;
	waitpid(pid, &status, 0);
	CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
	fclose(f);
	CHECK(got > 0);
}

static void test_dump_and_render(void)
{
	static struct run r;
	char dir[256], path[320];
	snprintf(dir, sizeof(dir), "%s/dump", d.dir);
	RUN(&r, NULL, "dump", dir);
	expect(&r, 0, "skyview.exr", "dump");
	static const char *const names[] = { "transmittance", "multiscatter", "skyview", "aerial" };
	for (int i = 0; i < 4; i++) {
		struct stat st;
		snprintf(path, sizeof(path), "%s/%s.exr", dir, names[i]);
		if (stat(path, &st) != 0 || st.st_size < 100)
			FAIL("dump: no %s", path);
	}
	static const struct {
		const char *view, *size;
		uint32_t w, h;
	} cases[] = {
		{ "fisheye", "96x96", 96, 96 },
		{ "equirect", "128x64", 128, 64 },
		{ "perspective", "80x45", 80, 45 },
		{ "fisheye", NULL, 1024, 1024 },
	};
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		uint32_t w = 0, h = 0;
		snprintf(path, sizeof(path), "%s/render-%zu.png", d.dir, i);
		if (cases[i].size)
			RUN(&r, NULL, "render", "--view", cases[i].view, "--size", cases[i].size, path);
		else
			RUN(&r, NULL, "render", "--view", cases[i].view, path);
		expect(&r, 0, NULL, cases[i].view);
		CHECK(png_size(path, &w, &h) == 0);
		if (w != cases[i].w || h != cases[i].h)
			FAIL("render %s: %ux%u, expected %ux%u", cases[i].view, w, h, cases[i].w, cases[i].h);
	}
}

/* SKYCTL_TIMEOUT_MS is the default of --timeout: against a peer that
 * greets and never answers, ping gives up after it, well before skyctl's
 * own 10 s; a value that is not a number is a usage error. */
static void test_timeout_env(void)
{
	static struct run r;
	struct sockaddr_un a = { .sun_family = AF_UNIX };
	const char *path = a.sun_path;
	if ((size_t)snprintf(a.sun_path, sizeof(a.sun_path), "%s.mute", d.sock) >= sizeof(a.sun_path)) {
		FAIL("%s.mute: too long for a socket's path", d.sock);
		return;
	}
	int l = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
	CHECK(l >= 0 && bind(l, (struct sockaddr *)&a, sizeof(a)) == 0 && listen(l, 1) == 0);
	pid_t pid = fork();
	if (pid == 0) {
		int s = accept(l, NULL, NULL);
		char buf[256];
		(void)!write(s, "OK skyd " SKY_PROTO_VERSION "\n", strlen("OK skyd " SKY_PROTO_VERSION "\n"));
		while (read(s, buf, sizeof(buf)) > 0)
			;
		_exit(0);
	}
	close(l);
	setenv("SKYCTL_TIMEOUT_MS", "300", 1);
	int64_t t0 = harness_now_ms();
	RUN(&r, NULL, "--socket", path, "ping");
	int64_t took_ms = harness_now_ms() - t0;
	expect(&r, 1, NULL, "ping a mute peer, SKYCTL_TIMEOUT_MS=300");
	if (!strstr(r.err, "timed out") || took_ms >= 5000)
		FAIL("ping a mute peer: %lld ms, stderr '%s'; expected 'timed out' after 300 ms",
		     (long long)took_ms, r.err);
	setenv("SKYCTL_TIMEOUT_MS", "soon", 1);
	RUN(&r, NULL, "ping");
	expect(&r, 2, NULL, "SKYCTL_TIMEOUT_MS=soon");
	CHECK(strstr(r.err, "SKYCTL_TIMEOUT_MS") != NULL);
	unsetenv("SKYCTL_TIMEOUT_MS");
	kill(pid, SIGTERM);	/* if skyctl never came, the peer still waits in accept */
	waitpid(pid, NULL, 0);
	unlink(path);
}

int main(void)
{
	harness_need_device();
	if (daemon_start(&d, small) < 0) {
		FAIL("skyd did not start");
		return test_report("test_skyctl");
	}
	/* a subscriber of ours, so the daemon computes every table */
	sky_client *c = NULL;
	CHECK(sky_connect(d.sock, &c) == 0);
	CHECK(c && sky_subscribe(c, SKY_TABLES_ALL, 0) == 0);
	for (int i = 0; c && sky_header(c) && i < 100; i++) {
		struct sky_view v;
		if (sky_view_begin(c, &v) == 0 && v.valid_tables == SKY_TABLES_ALL && sky_view_end(c, &v))
			break;
		if (sky_wait(c, v.generation, 30000, NULL) < 0)
			break;
	}
	test_verbs();
	sky_disconnect(c);
	test_watch();
	test_dump_and_render();
	test_timeout_env();
	daemon_cleanup(&d);
	return test_report("test_skyctl");
}
