/* test_units_notify.c - skyd as systemd runs it, with systemd's side
 * played by the test: socket activation through systemd-socket-activate,
 * READY, STATUS, the watchdog's keep-alives and STOPPING on a notify
 * socket of ours (scenario "activate"); SIGHUP re-reading the config file
 * all or nothing (scenario "reload"). "with SKYD CMD..." serves another
 * skyd (an installed one, or one under a wrapper) while CMD runs with
 * $SKYD_TEST_SOCKET naming its socket, and exits with CMD's status
 * (test_install.sh, test_units_sandbox.sh). */
#include <signal.h>
#include <sys/stat.h>

#include "daemon_harness.h"
#include "notify_harness.h"
#include "test.h"

#define WATCHDOG_USEC 1000000

static struct notify_sock ns;
static char dir[128];
static pid_t child;		/* killed when a check fails */

static void fail_exit(void)
{
	char cmd[256];

	if (child > 0)
		kill(child, SIGKILL);
	snprintf(cmd, sizeof(cmd), "cat '%s/skyd.log' >&2 2>/dev/null", dir);
	(void)!system(cmd);
	exit(1);
}

/* A check the rest of the scenario stands on. */
#define REQUIRE(cond)                          \
	do {                                   \
		test_checks++;                 \
		if (!(cond)) {                 \
			FAIL("%s", #cond);     \
			fail_exit();           \
		}                              \
	} while (0)

/* A reply's value of key, "" when absent. */
static const char *value_of(const char *reply, const char *key)
{
	static char buf[256];

	return reply_value(reply, key, buf, sizeof(buf)) ? buf : "";
}

/* Reads lines from fd until one contains needle; 0 or -1 (EOF). */
static int wait_output(int fd, const char *needle)
{
	char buf[4096];
	size_t len = 0;

	for (;;) {
		struct pollfd p = { fd, POLLIN, 0 };
		if (poll(&p, 1, HARNESS_TIMEOUT_MS) <= 0)
			return -1;
		ssize_t k = read(fd, buf + len, sizeof(buf) - 1 - len);
		if (k <= 0)
			return -1;
		len += (size_t)k;
		buf[len] = 0;
		if (strstr(buf, needle))
			return 0;
		if (len == sizeof(buf) - 1)
			len = 0;
	}
}

/* systemd-socket-activate listens on dir/control and execs skyd (same pid)
 * at the first connection, with NOTIFY_SOCKET and the watchdog's variables
 * as systemd sets them. */
static void activate(void)
{
	char sock[192], wpid[64], wusec[64], notify[160], reply[8192];
	struct notify_msg m;
	struct conn c;
	int out[2];

	if (access("/usr/bin/systemd-socket-activate", X_OK) != 0) {
		printf("skipped: systemd-socket-activate is missing\n");
		exit(77);
	}
	snprintf(sock, sizeof(sock), "%s/control", dir);
	REQUIRE(pipe2(out, O_CLOEXEC) == 0);
	pid_t pid = child = fork();
	if (pid == 0) {
		snprintf(notify, sizeof(notify), "NOTIFY_SOCKET=%s", ns.path);
		snprintf(wusec, sizeof(wusec), "WATCHDOG_USEC=%d", WATCHDOG_USEC);
		snprintf(wpid, sizeof(wpid), "WATCHDOG_PID=%d", (int)getpid());
		dup2(out[1], 2);
		execl("/usr/bin/systemd-socket-activate", "systemd-socket-activate", "-l", sock,
		      "-E", notify, "-E", wusec, "-E", wpid, SKYD_BINARY, HARNESS_SMALL, (char *)NULL);
		_exit(127);
	}
	close(out[1]);
	/* It says so on stderr once the socket listens. */
	REQUIRE(wait_output(out[0], "Listening on") == 0);
	REQUIRE(notify_sock_recv(&ns, 0, &m) == -ETIMEDOUT);	/* nothing before a client */

	/* The first client starts skyd and is served once it is ready. */
	REQUIRE(conn_open(&c, sock) == 0);
	REQUIRE(notify_sock_wait(&ns, "READY", "1", HARNESS_TIMEOUT_MS, &m) == 0);
	REQUIRE(m.pid == pid);
	const char *status = notify_msg_get(&m, "STATUS");
	REQUIRE(status && strstr(status, "generation ") && strstr(status, "clients ") &&
		    strstr(status, "last compute"));

	/* Keep-alives from skyd's own pid, well inside the watchdog's period. */
	long long prev = 0;
	for (int i = 0; i < 3; i++) {
		REQUIRE(notify_sock_wait(&ns, "WATCHDOG", "1", 2 * WATCHDOG_USEC / 1000, &m) == 0);
		REQUIRE(m.pid == pid);
		if (prev)
			REQUIRE(m.at_ns - prev < WATCHDOG_USEC * 1000LL);
		prev = m.at_ns;
	}

	/* A publication shows in STATUS: its generation and this client. */
	REQUIRE(conn_request(&c, "set sun_elevation_deg=7", reply, sizeof(reply)) == 0);
	uint64_t gen = reply_u64(reply, "generation");
	char want[64];
	snprintf(want, sizeof(want), "generation %llu, clients 1", (unsigned long long)gen);
	int seen = 0;
	while (!seen) {
		REQUIRE(notify_sock_wait(&ns, "STATUS", NULL, HARNESS_TIMEOUT_MS, &m) == 0);
		seen = strstr(notify_msg_get(&m, "STATUS"), want) != NULL;
	}
	conn_close(&c);

	kill(pid, SIGTERM);
	REQUIRE(notify_sock_wait(&ns, "STOPPING", "1", HARNESS_TIMEOUT_MS, &m) == 0);
	int st;
	REQUIRE(waitpid(pid, &st, 0) == pid && WIFEXITED(st) && WEXITSTATUS(st) == 0);
	child = 0;
	close(out[0]);
}

static void write_config(const char *path, const char *text)
{
	FILE *f = fopen(path, "w");

	REQUIRE(f && fputs(text, f) >= 0 && fclose(f) == 0);
}

/* Sends SIGHUP and waits for the reload's end: RELOADING=1, then READY=1. */
static void reload(pid_t pid)
{
	struct notify_msg m;

	kill(pid, SIGHUP);
	REQUIRE(notify_sock_wait(&ns, "RELOADING", "1", HARNESS_TIMEOUT_MS, &m) == 0);
	REQUIRE(notify_msg_get(&m, "MONOTONIC_USEC") != NULL);
	REQUIRE(notify_sock_wait(&ns, "READY", "1", HARNESS_TIMEOUT_MS, &m) == 0);
}

static int log_has(const char *path, const char *needle)
{
	char buf[1 << 16];
	FILE *f = fopen(path, "r");
	size_t n = f ? fread(buf, 1, sizeof(buf) - 1, f) : 0;

	if (f)
		fclose(f);
	buf[n] = 0;
	return strstr(buf, needle) != NULL;
}

/* A value the file gives that get shows alike but that differs in its
 * last bits is a change, its tables computed: the clock placed the sun
 * (its illuminance to every bit), the user took it over, and the file
 * names the illuminance with get's nine digits. */
static void reload_last_bits(struct conn *c, const char *conf, pid_t pid)
{
	char reply[8192], text[256];

	REQUIRE(conn_request(c, "set utc=2026-06-21T12:00:00Z lat_deg=48.2 lon_deg=16.4 time_rate=0",
			     reply, sizeof(reply)) == 0);
	REQUIRE(conn_request(c, "set sun_elevation_deg=14", reply, sizeof(reply)) == 0);
	uint64_t gen = reply_u64(reply, "generation");
	REQUIRE(conn_wait_generation(c, gen) == 0);
	REQUIRE(conn_request(c, "get sun_illuminance_lx", reply, sizeof(reply)) == 0);
	snprintf(text, sizeof(text), "sun_elevation_deg = 14\nground_albedo = 0.2\n"
		 "max_connections = 77\nsun_illuminance_lx = %s\n", value_of(reply, "sun_illuminance_lx"));
	write_config(conf, text);
	reload(pid);
	REQUIRE(conn_request(c, "status", reply, sizeof(reply)) == 0);
	if (reply_u64(reply, "computing") != 1 && reply_u64(reply, "generation") != gen + 1)
		FAIL("sun_illuminance_lx from the file computed nothing: generation %llu",
		     (unsigned long long)reply_u64(reply, "generation"));
	else
		REQUIRE(conn_wait_generation(c, gen + 1) == 0);
}

static void reload_scenario(void)
{
	char sock[192], conf[192], logp[192], reply[8192];
	struct notify_msg m;
	struct conn c;

	snprintf(sock, sizeof(sock), "%s/control", dir);
	snprintf(conf, sizeof(conf), "%s/skyd.conf", dir);
	snprintf(logp, sizeof(logp), "%s/skyd.log", dir);
	write_config(conf, "# as shipped\nsun_elevation_deg = 30\n");
	pid_t pid = child = fork();
	if (pid == 0) {
		int fd = open(logp, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0600);
		dup2(fd, 2);
		setenv("NOTIFY_SOCKET", ns.path, 1);
		execl(SKYD_BINARY, SKYD_BINARY, "--socket", sock, "--config", conf, HARNESS_SMALL,
		      (char *)NULL);
		_exit(127);
	}
	REQUIRE(notify_sock_wait(&ns, "READY", "1", HARNESS_TIMEOUT_MS, &m) == 0);
	REQUIRE(conn_open(&c, sock) == 0);
	REQUIRE(conn_request(&c, "get sun_elevation_deg", reply, sizeof(reply)) == 0);
	REQUIRE(strcmp(value_of(reply, "sun_elevation_deg"), "30") == 0);

	REQUIRE(conn_request(&c, "status", reply, sizeof(reply)) == 0);
	REQUIRE(reply_u64(reply, "max_connections") == 1024);

	/* A changed, valid file applies, the daemon's own settings with it. */
	write_config(conf, "sun_elevation_deg = 12.5\nground_albedo = 0.2\nmax_connections = 77\n");
	reload(pid);
	REQUIRE(conn_request(&c, "status", reply, sizeof(reply)) == 0);
	REQUIRE(reply_u64(reply, "max_connections") == 77);
	REQUIRE(conn_request(&c, "get sun_elevation_deg ground_albedo", reply,
				 sizeof(reply)) == 0);
	REQUIRE(strcmp(value_of(reply, "sun_elevation_deg"), "12.5") == 0);
	REQUIRE(strcmp(value_of(reply, "ground_albedo"), "0.2,0.2,0.2") == 0);
	REQUIRE(log_has(logp, "reload: ") && log_has(logp, "applied"));

	/* A file bad on its last line is refused whole: its first line does
	 * not apply, the generation stays. First the sky comes to rest: a
	 * change's generation, waited for. */
	REQUIRE(conn_request(&c, "subscribe tables=all events=1", reply, sizeof(reply)) == 0);
	c.event_generation = reply_u64(reply, "generation");	/* published */
	REQUIRE(conn_request(&c, "set ground_albedo=0.2", reply, sizeof(reply)) == 0);
	uint64_t gen = reply_u64(reply, "generation");
	REQUIRE(conn_wait_generation(&c, gen) == 0);
	REQUIRE(conn_request(&c, "status", reply, sizeof(reply)) == 0);
	REQUIRE(reply_u64(reply, "generation") == gen);
	write_config(conf, "sun_elevation_deg = 40\nmax_connections = 9\nground_albedo = 7\n");
	reload(pid);
	REQUIRE(log_has(logp, "reload refused"));
	REQUIRE(conn_request(&c, "status", reply, sizeof(reply)) == 0);
	REQUIRE(reply_u64(reply, "max_connections") == 77);
	REQUIRE(conn_request(&c, "get sun_elevation_deg ground_albedo", reply,
				 sizeof(reply)) == 0);
	REQUIRE(strcmp(value_of(reply, "sun_elevation_deg"), "12.5") == 0);
	REQUIRE(strcmp(value_of(reply, "ground_albedo"), "0.2,0.2,0.2") == 0);
	REQUIRE(conn_request(&c, "status", reply, sizeof(reply)) == 0);
	REQUIRE(reply_u64(reply, "generation") == gen);
	REQUIRE(reply_u64(reply, "computing") == 0 && reply_u64(reply, "pending") == 0);

	/* A reload recomputes only what its changed keys invalidate: the sun
	 * moves sky-view and aerial perspective, not transmittance. */
	write_config(conf, "sun_elevation_deg = 14\nground_albedo = 0.2\nmax_connections = 77\n");
	reload(pid);
	REQUIRE(conn_wait_generation(&c, gen + 1) == 0);
	REQUIRE(conn_request(&c, "status", reply, sizeof(reply)) == 0);
	REQUIRE(reply_u64(reply, "generation") == gen + 1);
	if (strcmp(value_of(reply, "tables_computed"), "skyview,aerial") != 0)
		FAIL("tables_computed: %s", value_of(reply, "tables_computed"));

	reload_last_bits(&c, conf, pid);

	/* An unreadable file too; skyd keeps serving. */
	REQUIRE(unlink(conf) == 0);
	reload(pid);
	REQUIRE(conn_request(&c, "get sun_elevation_deg", reply, sizeof(reply)) == 0);
	REQUIRE(strcmp(value_of(reply, "sun_elevation_deg"), "14") == 0);
	conn_close(&c);

	kill(pid, SIGTERM);
	int st;
	REQUIRE(waitpid(pid, &st, 0) == pid && WIFEXITED(st) && WEXITSTATUS(st) == 0);
	child = 0;
}

/* Starts skyd (a path) on dir/control, waits for READY=1, runs cmd with
 * SKYD_TEST_SOCKET set, stops skyd; cmd's exit status, or 1. */
static int with_skyd(const char *skyd, char **cmd)
{
	char sock[192], logp[192];
	struct notify_msg m;
	int st;

	snprintf(sock, sizeof(sock), "%s/control", dir);
	snprintf(logp, sizeof(logp), "%s/skyd.log", dir);
	child = fork();
	if (child == 0) {
		int fd = open(logp, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0600);
		dup2(fd, 2);
		setenv("NOTIFY_SOCKET", ns.path, 1);
		execl(skyd, skyd, "--socket", sock, HARNESS_SMALL, (char *)NULL);
		_exit(127);
	}
	REQUIRE(notify_sock_wait(&ns, "READY", "1", HARNESS_TIMEOUT_MS, &m) == 0);
	/* skyd itself, which may run under a wrapper (test_units_sandbox.sh). */
	pid_t skyd_pid = m.pid;
	pid_t run = fork();
	if (run == 0) {
		setenv("SKYD_TEST_SOCKET", sock, 1);
		execvp(cmd[0], cmd);
		_exit(127);
	}
	REQUIRE(waitpid(run, &st, 0) == run);
	kill(skyd_pid, SIGTERM);
	REQUIRE(notify_sock_wait(&ns, "STOPPING", "1", HARNESS_TIMEOUT_MS, &m) == 0);
	int dst;
	REQUIRE(waitpid(child, &dst, 0) == child && WIFEXITED(dst) && WEXITSTATUS(dst) == 0);
	child = 0;
	return WIFEXITED(st) ? WEXITSTATUS(st) : 1;
}

int main(int argc, char **argv)
{
	char cmd[192];

	if (argc >= 4 && strcmp(argv[1], "with") == 0) {
		harness_need_device();
		REQUIRE(harness_mkdtemp(dir, sizeof(dir)) == 0);
		REQUIRE(notify_sock_open(&ns, dir) == 0);
		int r = with_skyd(argv[2], argv + 3);
		notify_sock_close(&ns);
		snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
		(void)!system(cmd);
		return r;
	}
	if (argc != 2) {
		fprintf(stderr, "usage: test_units_notify activate|reload|with SKYD CMD...\n");
		return 2;
	}
	harness_need_device();
	REQUIRE(harness_mkdtemp(dir, sizeof(dir)) == 0);
	REQUIRE(notify_sock_open(&ns, dir) == 0);
	if (strcmp(argv[1], "activate") == 0)
		activate();
	else
		reload_scenario();
	notify_sock_close(&ns);
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
	(void)!system(cmd);
	return test_report(argv[1]);
}
