/* test_refusals.c - nonsense atmospheres are refused alike at the control
 * protocol, in a config file (skyd -n --config FILE) and on the command line
 * (skyd -n key=value), each time with a message naming the key; over the
 * protocol the state and the published generation stay as they were. */
#include <fcntl.h>
#include <sys/wait.h>

#include "daemon_harness.h"
#include "test.h"

static char reply[1 << 16];

/* key=value, and the key the message must name. */
static const char *const bad[][2] = {
	{ "top_radius_km=6000", "top_radius_km" },	/* below the ground */
	{ "top_radius_km=6360", "top_radius_km" },	/* equal to it */
	{ "bottom_radius_km=6460", "bottom_radius_km" },
	{ "rayleigh_scattering_per_km=-1", "rayleigh_scattering_per_km" },
	{ "mie_absorption_per_km=0.1,-1e-3,0.1", "mie_absorption_per_km" },
	{ "ozone_absorption_per_km=nan", "ozone_absorption_per_km" },
	{ "rayleigh_scale_height_km=inf", "rayleigh_scale_height_km" },
	{ "sun_elevation_deg=nan", "sun_elevation_deg" },
	{ "altitude_km=-inf", "altitude_km" },
	{ "mie_g=1", "mie_g" },
	{ "mie_g=-1", "mie_g" },
	{ "mie_g=1.5", "mie_g" },
	{ "mie_g=nan", "mie_g" },
	{ "ground_albedo=1.5", "ground_albedo" },
	{ "ground_albedo=-0.1", "ground_albedo" },
	{ "ground_albedo=0.3,inf,0.3", "ground_albedo" },
};
#define N_BAD (sizeof(bad) / sizeof(bad[0]))

/* Runs skyd -n with args; returns its exit status and leaves stderr in err. */
static int run_check(const char *dir, const char *const *args, char *err, size_t size)
{
	char path[256];
	const char *argv[8] = { SKYD_BINARY, "-n" };
	int n = 2;
	for (; *args && n < 7; args++)
		argv[n++] = *args;
	argv[n] = NULL;
	snprintf(path, sizeof(path), "%s/stderr", dir);
	pid_t pid = fork();
	if (pid == 0) {
		int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
		dup2(fd, 2);
		dup2(fd, 1);
		execv(SKYD_BINARY, (char *const *)argv);
		_exit(127);
	}
	int status;
	waitpid(pid, &status, 0);
	FILE *f = fopen(path, "re");
	size_t got = f ? fread(err, 1, size - 1, f) : 0;
	err[got] = 0;
	if (f)
		fclose(f);
	return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
}

static void test_protocol(struct conn *c)
{
	char before[1 << 14], after[1 << 14], req[256];
	/* Wait until a generation is published, so that nothing legitimate
	 * moves it while the refusals go in. */
	CHECK(conn_request(c, "subscribe tables=all events=1", reply, sizeof(reply)) == 0);
	CHECK(conn_request(c, "set sun_elevation_deg=11", reply, sizeof(reply)) == 0);
	CHECK(conn_wait_generation(c, reply_u64(reply, "generation")) == 0);
	CHECK(conn_request(c, "get", before, sizeof(before)) == 0);
	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	uint64_t gen = reply_u64(reply, "generation");
	for (size_t i = 0; i < N_BAD; i++) {
		snprintf(req, sizeof(req), "set %s", bad[i][0]);
		int code = conn_request(c, req, reply, sizeof(reply));
		if (code <= 0 || !strstr(reply, bad[i][1]))
			FAIL("protocol: '%s' gave %d '%s', not an ACK naming %s", req, code, reply, bad[i][1]);
		/* The same inside a batch (batch and its lines answer nothing;
		 * end answers for all): nothing applied either. */
		char msg[512];
		snprintf(msg, sizeof(msg), "batch\nset sun_elevation_deg=7\nset %s\nend", bad[i][0]);
		code = conn_request(c, msg, reply, sizeof(reply));
		if (code <= 0 || !strstr(reply, bad[i][1]))
			FAIL("protocol batch: '%s' gave %d '%s', not an ACK naming %s", bad[i][0], code, reply,
			     bad[i][1]);
	}
	CHECK(conn_request(c, "get", after, sizeof(after)) == 0);
	CHECK(strcmp(before, after) == 0);
	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	CHECK(gen > 0 && gen != UINT64_MAX && reply_u64(reply, "generation") == gen);
	printf("protocol: %zu refusals, set and batch, state and generation %llu unchanged\n", N_BAD,
	       (unsigned long long)gen);
}

static void test_config_and_cli(const char *dir)
{
	char path[256], err[4096];
	for (size_t i = 0; i < N_BAD; i++) {
		snprintf(path, sizeof(path), "%s/bad.conf", dir);
		FILE *f = fopen(path, "we");
		const char *eq = strchr(bad[i][0], '=');
		fprintf(f, "# a config with one bad line\nsun_elevation_deg = 12\n%.*s = %s\n",
			(int)(eq - bad[i][0]), bad[i][0], eq + 1);
		fclose(f);
		int rc = run_check(dir, (const char *const[]){ "--config", path, NULL }, err, sizeof(err));
		if (rc == 0 || !strstr(err, bad[i][1]))
			FAIL("config: '%s' exited %d with '%s'", bad[i][0], rc, err);
		rc = run_check(dir, (const char *const[]){ bad[i][0], NULL }, err, sizeof(err));
		if (rc == 0 || !strstr(err, bad[i][1]))
			FAIL("command line: '%s' exited %d with '%s'", bad[i][0], rc, err);
	}
	/* The check itself accepts a good state. */
	int rc = run_check(dir, (const char *const[]){ "mie_g=0.999", "ground_albedo=1", NULL }, err,
			   sizeof(err));
	CHECK(rc == 0);
	printf("config file and command line: %zu refusals each\n", N_BAD);
}

int main(void)
{
	struct daemon d = { 0 };
	struct conn c;
	harness_need_device();
	const char *args[] = { HARNESS_SMALL, NULL };
	if (daemon_start(&d, args) < 0) {
		FAIL("skyd did not start");
		return test_report("test_refusals");
	}
	if (conn_open(&c, d.sock) < 0) {
		FAIL("connect");
	} else {
		test_protocol(&c);
		conn_close(&c);
	}
	test_config_and_cli(d.dir);
	daemon_cleanup(&d);
	return test_report("test_refusals");
}
