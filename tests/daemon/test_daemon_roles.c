/* test_daemon_roles.c - roles and bounds of the control socket with the
 * real skyd and real peers of two uids: root (the test) and nobody (65534,
 * a forked child that drops to it). Scenarios, one per argument:
 *   roles        a reader gets, subscribes and samples; every change it
 *                asks for is ACK 4 naming the role, and nothing changes
 *   groups       controllers=@GID: a peer with that supplementary group
 *                controls, one without reads; skyd's own uid controls
 *   connections  past max_connections: one ACK line, then EOF; those
 *                connected are still answered; a freed place is taken
 *   throttle     many refused connections of two uids: one log line each
 *   bounds       max_subscriptions_per_uid and max_views_per_uid count
 *                per uid
 *   config       the settings refused at skyd -n naming the key
 *   socketdir    a socket in a directory others may write is refused with
 *                advice that works when followed
 * The scenarios with a second uid exit 77 (skipped) when not root. */
#include <grp.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include "daemon_harness.h"
#include "sky.h"
#include "test.h"

#define NOBODY 65534
#define SOME_GID 4242		/* a supplementary group given to nobody */

static char reply[1 << 16];

static void need_root(void)
{
	if (geteuid() != 0) {
		printf("skipped: a second uid needs root (the test drops to uid %d)\n", NOBODY);
		exit(77);
	}
}

/* Lets nobody reach the socket, as SocketMode=0666 of a socket unit would:
 * the test's directory is 0700 and the socket skyd makes is for its uid. */
static void open_to_all(const struct daemon *d)
{
	CHECK(chmod(d->dir, 0711) == 0);
	CHECK(chmod(d->sock, 0666) == 0);
}

/* Runs fn(sock) in a child as uid NOBODY with the supplementary groups
 * given; its failed checks come back as its exit status. A child that
 * cannot reach the socket (a $TMPDIR closed to others) skips the test. */
static void as_nobody(const gid_t *groups, int n_groups, void (*fn)(const char *sock),
		      const char *sock)
{
	int status;

	fflush(stdout);
	fflush(stderr);
	pid_t pid = fork();
	if (pid == 0) {
		if (setgroups((size_t)n_groups, groups) < 0 || setgid(NOBODY) < 0 ||
		    setuid(NOBODY) < 0) {
			perror("dropping to nobody");
			_exit(100);
		}
		if (access(sock, W_OK) < 0) {
			printf("skipped: uid %d cannot reach %s\n", NOBODY, sock);
			_exit(77);
		}
		fn(sock);
		_exit(test_failures ? 1 : 0);
	}
	CHECK(pid > 0 && waitpid(pid, &status, 0) == pid);
	if (WIFEXITED(status) && WEXITSTATUS(status) == 77)
		exit(77);
	if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
		FAIL("the child as uid %d failed (status %#x)", NOBODY, status);
}

/* The request must be refused with ACK code, its line holding want. */
static void expect_ack(struct conn *c, const char *req, int code, const char *want)
{
	int got = conn_request(c, req, reply, sizeof(reply));

	if (got != code || !strstr(reply, want))
		FAIL("'%s': %d '%s', expected ACK %d with '%s'", req, got, reply, code, want);
}

static void expect_ok(struct conn *c, const char *req)
{
	int got = conn_request(c, req, reply, sizeof(reply));

	if (got != 0)
		FAIL("'%s': %d '%s', expected OK", req, got, reply);
}

static void expect_role(struct conn *c, const char *role)
{
	char buf[32];

	expect_ok(c, "status");
	if (!reply_value(reply, "role", buf, sizeof(buf)) || strcmp(buf, role) != 0)
		FAIL("status says role '%s', expected '%s'", reply_value(reply, "role", buf, sizeof(buf)) ? buf : "(none)", role);
}

/* roles ------------------------------------------------------------------ */

static void reader_session(const char *sock)
{
	static const char *const changes[] = {
		"set sun_elevation_deg=3", "batch", "end", "view add name=mine",
		"view del name=mine", "sensor list", "sensor events=1",
	};
	struct conn c;
	char want[128];

	CHECK(conn_open(&c, sock) == 0);
	expect_role(&c, "reader");
	expect_ok(&c, "get sun_elevation_deg");
	expect_ok(&c, "subscribe tables=all events=1");
	CHECK(c.n_fds == 1);
	expect_ok(&c, "sample sun");
	expect_ok(&c, "view list");
	expect_ok(&c, "help set");
	for (size_t i = 0; i < sizeof(changes) / sizeof(changes[0]); i++) {
		char verb[16];
		snprintf(verb, sizeof(verb), "%.*s", (int)strcspn(changes[i], " "), changes[i]);
		snprintf(want, sizeof(want), "ACK [4] {%s} controller role needed: uid %d reads only (controllers = root",
			 verb, NOBODY);
		expect_ack(&c, changes[i], 4, want);
	}
	/* The refused batch opened nothing: set is refused as set, at once. */
	expect_ack(&c, "set sun_elevation_deg=4", 4, "{set}");
	expect_ok(&c, "ping");
	conn_close(&c);
}

static void scenario_roles(void)
{
	struct daemon d;
	struct conn c;
	static char before[sizeof(reply)], after[sizeof(reply)];

	need_root();
	CHECK(daemon_start(&d, (const char *const[]){ HARNESS_SMALL, NULL }) == 0);
	open_to_all(&d);
	CHECK(conn_open(&c, d.sock) == 0);
	expect_role(&c, "controller");
	CHECK(reply_u64(reply, "controller_clients") == 1);
	CHECK(reply_u64(reply, "max_connections") == 1024);
	/* All tables in demand already: the reader's subscription adds none,
	 * so nothing it may do moves the generation. */
	expect_ok(&c, "subscribe tables=all events=1");
	expect_ok(&c, "set sun_elevation_deg=21");
	CHECK(conn_wait_generation(&c, reply_u64(reply, "generation")) == 0);
	expect_ok(&c, "get");
	snprintf(before, sizeof(before), "%s", reply);
	expect_ok(&c, "status");
	uint64_t generation = reply_u64(reply, "generation");

	as_nobody(NULL, 0, reader_session, d.sock);

	expect_ok(&c, "get");
	snprintf(after, sizeof(after), "%s", reply);
	CHECK(strcmp(before, after) == 0);
	expect_ok(&c, "status");
	CHECK(reply_u64(reply, "generation") == generation);
	CHECK(reply_u64(reply, "views") == 0);
	expect_ok(&c, "set sun_elevation_deg=7");
	conn_close(&c);
	daemon_cleanup(&d);
}

/* groups ----------------------------------------------------------------- */

static void group_controller(const char *sock)
{
	struct conn c;

	CHECK(conn_open(&c, sock) == 0);
	expect_role(&c, "controller");
	expect_ok(&c, "set sun_elevation_deg=9");
	expect_ok(&c, "view add name=grouped");
	conn_close(&c);
}

static void group_reader(const char *sock)
{
	struct conn c;

	CHECK(conn_open(&c, sock) == 0);
	expect_role(&c, "reader");
	expect_ack(&c, "set sun_elevation_deg=9", 4, "(controllers = @4242)");
	conn_close(&c);
}

static void scenario_groups(void)
{
	const gid_t in_group[] = { 100, SOME_GID };
	struct daemon d;
	struct conn c;

	need_root();
	CHECK(daemon_start(&d, (const char *const[]){ "--controllers", "@4242", HARNESS_SMALL,
						      NULL }) == 0);
	open_to_all(&d);
	as_nobody(in_group, 2, group_controller, d.sock);
	as_nobody(NULL, 0, group_reader, d.sock);
	/* Not listed, but skyd's own uid. */
	CHECK(conn_open(&c, d.sock) == 0);
	expect_role(&c, "controller");
	expect_ok(&c, "set sun_elevation_deg=10");
	conn_close(&c);
	daemon_cleanup(&d);
}

/* connections and throttle ----------------------------------------------- */

/* Everything skyd sends until it closes, into buf; -1 on a timeout. */
static int read_to_eof(int fd, char *buf, size_t size)
{
	size_t len = 0;

	for (;;) {
		struct pollfd p = { fd, POLLIN, 0 };
		if (poll(&p, 1, HARNESS_TIMEOUT_MS) <= 0)
			return -1;
		ssize_t n = read(fd, buf + len, size - 1 - len);
		if (n < 0)
			return -1;
		if (n == 0)
			break;
		len += (size_t)n;
	}
	buf[len] = 0;
	return (int)len;
}

/* A connection past the bound: exactly one ACK [52] {connect} line, then
 * EOF. */
static void expect_refused_n(const char *sock, unsigned max)
{
	char buf[1024], want[96];
	int fd = conn_raw(sock);

	CHECK(fd >= 0);
	int n = fd >= 0 ? read_to_eof(fd, buf, sizeof(buf)) : -1;
	snprintf(want, sizeof(want), "ACK [52] {connect} too many connections (max_connections = %u)",
		 max);
	if (n < 0 || strncmp(buf, want, strlen(want)) || strchr(buf, '\n') != buf + n - 1)
		FAIL("refused connection: %d '%s', expected one ACK [52] {connect} line and EOF", n,
		     n < 0 ? "" : buf);
	if (fd >= 0)
		close(fd);
}

static void expect_refused(const char *sock)
{
	expect_refused_n(sock, 3);
}

/* Waits until skyd counts n clients (it notices a close when it reads). */
static void wait_clients(struct conn *c, uint64_t n)
{
	for (int i = 0; i < 100000; i++) {
		if (conn_request(c, "status", reply, sizeof(reply)) != 0)
			break;
		if (reply_u64(reply, "clients") == n)
			return;
	}
	FAIL("skyd never counted %llu clients", (unsigned long long)n);
}

static void scenario_connections(void)
{
	struct daemon d;
	struct conn c[3], e;

	CHECK(daemon_start(&d, (const char *const[]){ "--max-connections", "3", HARNESS_SMALL,
						      NULL }) == 0);
	for (int i = 0; i < 3; i++)
		CHECK(conn_open(&c[i], d.sock) == 0);
	expect_ok(&c[0], "subscribe events=1");
	for (int i = 0; i < 5; i++)
		expect_refused(d.sock);
	/* libsky says what the refusal means: try again later. */
	sky_client *sc = NULL;
	CHECK(sky_connect(d.sock, &sc) == -EAGAIN && !sc);
	for (int i = 0; i < 3; i++)
		expect_ok(&c[i], "ping");
	expect_ok(&c[1], "set sun_elevation_deg=17");
	CHECK(conn_wait_generation(&c[0], reply_u64(reply, "generation")) == 0);
	/* A place freed is a place taken. */
	conn_close(&c[2]);
	wait_clients(&c[0], 2);
	CHECK(conn_open(&e, d.sock) == 0);
	expect_ok(&e, "ping");
	expect_refused(d.sock);
	conn_close(&e);
	for (int i = 0; i < 2; i++)
		conn_close(&c[i]);
	daemon_cleanup(&d);
}

/* reserve ----------------------------------------------------------------- */

#define RESERVE_MAX 32		/* max_connections; the last 32 / 16 = 2 for controllers */

/* The refusal as a reader meets it in the controllers' reserve. */
static void expect_reserved(const char *sock)
{
	char buf[1024];
	int fd = conn_raw(sock);
	int n = fd >= 0 ? read_to_eof(fd, buf, sizeof(buf)) : -1;

	if (n < 0 || !strstr(buf, "ACK [52] {connect} too many connections (max_connections = 32, "
				   "the last places kept for controllers)"))
		FAIL("reader in the reserve: %d '%s'", n, n < 0 ? "" : buf);
	if (fd >= 0)
		close(fd);
}

static void scenario_reserve(void)
{
	struct daemon d;
	struct conn mine, readers[RESERVE_MAX], extra[2];
	int ready[2], done[2], status;
	char byte = 0;

	need_root();
	CHECK(daemon_start(&d, (const char *const[]){ "--max-connections", "32", HARNESS_SMALL,
						      NULL }) == 0);
	open_to_all(&d);
	CHECK(conn_open(&mine, d.sock) == 0);
	CHECK(pipe(ready) == 0 && pipe(done) == 0);
	fflush(stdout);
	pid_t pid = fork();
	if (pid == 0) {
		/* nobody fills what readers may take: 32 - 2 - the root one. */
		if (setgroups(0, NULL) < 0 || setgid(NOBODY) < 0 || setuid(NOBODY) < 0)
			_exit(100);
		for (int i = 0; i < RESERVE_MAX - 2 - 1; i++)
			CHECK(conn_open(&readers[i], d.sock) == 0);
		expect_reserved(d.sock);
		expect_reserved(d.sock);
		(void)!write(ready[1], &byte, 1);
		(void)!read(done[0], &byte, 1);
		_exit(test_failures ? 1 : 0);
	}
	CHECK(pid > 0 && read(ready[0], &byte, 1) == 1);
	/* The controllers' two places, then nobody's. */
	for (int i = 0; i < 2; i++) {
		CHECK(conn_open(&extra[i], d.sock) == 0);
		expect_ok(&extra[i], "set sun_elevation_deg=9");
	}
	expect_refused_n(d.sock, RESERVE_MAX);
	(void)!write(done[1], &byte, 1);
	CHECK(waitpid(pid, &status, 0) == pid && WIFEXITED(status) && WEXITSTATUS(status) == 0);
	for (int i = 0; i < 2; i++)
		conn_close(&extra[i]);
	conn_close(&mine);
	daemon_cleanup(&d);
}

static void refused_twenty(const char *sock)
{
	for (int i = 0; i < 20; i++)
		expect_refused(sock);
}

/* Lines of the log holding text. */
static int count_log_lines(const char *log, const char *text)
{
	char line[2048];
	int n = 0;
	FILE *f = fopen(log, "re");

	if (!f)
		return -1;
	while (fgets(line, sizeof(line), f))
		n += strstr(line, text) != NULL;
	fclose(f);
	return n;
}

static void scenario_throttle(void)
{
	struct daemon d;
	struct conn c[3];
	char want[64];

	need_root();
	CHECK(daemon_start(&d, (const char *const[]){ "--max-connections", "3", HARNESS_SMALL,
						      NULL }) == 0);
	open_to_all(&d);
	for (int i = 0; i < 3; i++)
		CHECK(conn_open(&c[i], d.sock) == 0);
	for (int i = 0; i < 50; i++)
		expect_refused(d.sock);
	as_nobody(NULL, 0, refused_twenty, d.sock);
	for (int i = 0; i < 30; i++)
		expect_refused(d.sock);
	/* skyd logs before it closes: the EOFs above came after the lines. */
	CHECK(count_log_lines(d.log, "refused: 3 clients, max_connections = 3") == 2);
	snprintf(want, sizeof(want), "connection from uid %d ", NOBODY);
	CHECK(count_log_lines(d.log, want) == 1);
	CHECK(count_log_lines(d.log, "connection from uid 0 ") == 1);
	for (int i = 0; i < 3; i++) {
		expect_ok(&c[i], "ping");
		conn_close(&c[i]);
	}
	daemon_cleanup(&d);
}

/* bounds ----------------------------------------------------------------- */

static void nobody_subscribes_and_adds(const char *sock)
{
	struct conn c;

	CHECK(conn_open(&c, sock) == 0);
	expect_ok(&c, "subscribe events=1");
	expect_ok(&c, "view add name=theirs");
	conn_close(&c);
}

static void scenario_bounds(void)
{
	struct daemon d;
	struct conn c[3];
	char want[128];

	CHECK(daemon_start(&d, (const char *const[]){ "--controllers", "root,65534",
						      "--max-subscriptions-per-uid", "2",
						      "--max-views-per-uid", "2", HARNESS_SMALL, NULL }) == 0);
	for (int i = 0; i < 3; i++)
		CHECK(conn_open(&c[i], d.sock) == 0);
	expect_ok(&c[0], "subscribe events=1");
	expect_ok(&c[1], "subscribe tables=all");
	snprintf(want, sizeof(want),
		 "{subscribe} uid %d holds 2 subscriptions (max_subscriptions_per_uid = 2)",
		 (int)geteuid());
	expect_ack(&c[2], "subscribe events=1", 52, want);
	expect_ack(&c[2], "subscribe tables=skyview", 52, "max_subscriptions_per_uid = 2");
	CHECK(c[2].n_fds == 0);
	expect_ok(&c[2], "subscribe events=0");		/* holds nothing: allowed */
	expect_ok(&c[0], "subscribe tables=all events=1");	/* already holds one */
	expect_ok(&c[0], "view add name=a");
	expect_ok(&c[1], "view add name=b");
	snprintf(want, sizeof(want), "{view} uid %d holds 2 views (max_views_per_uid = 2)",
		 (int)geteuid());
	expect_ack(&c[2], "view add name=c", 52, want);
	expect_ok(&c[0], "view add name=a yaw_deg=90");	/* replacing is no new view */
	if (geteuid() == 0) {
		open_to_all(&d);
		as_nobody(NULL, 0, nobody_subscribes_and_adds, d.sock);
	}
	expect_ok(&c[0], "unsubscribe");
	expect_ok(&c[2], "subscribe events=1");
	expect_ok(&c[0], "view del name=a");
	expect_ok(&c[2], "view add name=c");
	for (int i = 0; i < 3; i++)
		conn_close(&c[i]);
	daemon_cleanup(&d);
}

/* config ----------------------------------------------------------------- */

/* skyd -n with args: its exit status, its output in out. */
static int check_config(const char *const *args, char *out, size_t size)
{
	char cmd[1024];
	size_t o = (size_t)snprintf(cmd, sizeof(cmd), "%s -n", SKYD_BINARY);

	for (; *args; args++)
		o += (size_t)snprintf(cmd + o, sizeof(cmd) - o, " '%s'", *args);
	snprintf(cmd + o, sizeof(cmd) - o, " 2>&1");
	FILE *p = popen(cmd, "re");
	size_t got = p ? fread(out, 1, size - 1, p) : 0;
	out[got] = 0;
	int status = p ? pclose(p) : -1;
	return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

static void scenario_config(void)
{
	static const char *const bad[][3] = {
		{ "--controllers", "root,@no-such-group-here", "no group 'no-such-group-here'" },
		{ "--controllers", "no-such-user-here", "no user 'no-such-user-here'" },
		{ "--controllers", "12x", "'12x' is not a valid uid" },
		{ "--max-connections", "0", "--max-connections: a whole number from 1 to 4096" },
		{ "--max-connections", "4097", "--max-connections: a whole number from 1 to 4096" },
		{ "--max-views-per-uid", "-1", "--max-views-per-uid: a whole number" },
		{ "--max-subscriptions-per-uid", "2x", "--max-subscriptions-per-uid: a whole number" },
	};
	char out[2048], dir[128], path[192];
	FILE *f;

	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		int rc = check_config((const char *const[]){ bad[i][0], bad[i][1], NULL }, out,
				      sizeof(out));
		if (rc != 1 || !strstr(out, bad[i][2]))
			FAIL("skyd -n %s %s: %d '%s', expected 1 and '%s'", bad[i][0], bad[i][1], rc,
			     out, bad[i][2]);
	}
	CHECK(check_config((const char *const[]){ "--controllers", "root, 0 ,@0", "--max-connections",
						  "4096", NULL }, out, sizeof(out)) == 0);
	CHECK(harness_mkdtemp(dir, sizeof(dir)) == 0);
	snprintf(path, sizeof(path), "%s/skyd.conf", dir);
	f = fopen(path, "we");
	fprintf(f, "controllers = root, @0\nmax_connections = 8\nmax_views_per_uid = 0\n"
		   "max_subscriptions_per_uid = 99999\n");
	fclose(f);
	CHECK(check_config((const char *const[]){ "--config", path, NULL }, out, sizeof(out)) == 1);
	CHECK(strstr(out, "skyd.conf:4: max_subscriptions_per_uid: a whole number from 0 to 4096"));
	snprintf(reply, sizeof(reply), "rm -rf '%s'", dir);
	(void)!system(reply);
}

/* socketdir -------------------------------------------------------------- */

static void scenario_socketdir(void)
{
	char dir[128], shared[192], sock[256], text[4096], cmd[512];
	struct daemon d = { 0 };
	struct conn c;
	struct stat st;

	CHECK(harness_mkdtemp(dir, sizeof(dir)) == 0);
	snprintf(shared, sizeof(shared), "%s/shared", dir);
	CHECK(mkdir(shared, 0700) == 0 && chmod(shared, 01777) == 0);	/* like /tmp */
	snprintf(sock, sizeof(sock), "%s/control", shared);
	CHECK(daemon_start_in(&d, dir, (const char *const[]){ "--socket", sock, HARNESS_SMALL,
							      NULL }) == -1);
	waitpid(d.pid, NULL, 0);
	close(d.pidfd);
	FILE *f = fopen(d.log, "re");
	size_t n = f ? fread(text, 1, sizeof(text) - 1, f) : 0;
	text[n] = 0;
	if (f)
		fclose(f);
	CHECK(strstr(text, "is writable by others (mode 1777)"));
	CHECK(strstr(text, "a directory of its own"));
	CHECK(!strstr(text, "chmod"));
	/* The advice, followed, works. */
	const char *advice = strstr(text, "e.g. --socket ");
	CHECK(advice);
	if (!advice)
		return;
	snprintf(sock, sizeof(sock), "%.*s", (int)strcspn(advice + 14, " \n"), advice + 14);
	snprintf(cmd, sizeof(cmd), "%s/skyd-%d/control", shared, (int)geteuid());
	CHECK(strcmp(sock, cmd) == 0);
	CHECK(daemon_start_in(&d, dir, (const char *const[]){ "--socket", sock, HARNESS_SMALL,
							      NULL }) == 0);
	CHECK(conn_open(&c, sock) == 0);
	expect_ok(&c, "ping");
	conn_close(&c);
	*strrchr(sock, '/') = 0;
	CHECK(stat(sock, &st) == 0 && (st.st_mode & 07777) == 0700 && st.st_uid == geteuid());
	daemon_cleanup(&d);
}

int main(int argc, char **argv)
{
	static const struct {
		const char *name;
		void (*fn)(void);
	} scenarios[] = {
		{ "roles", scenario_roles }, { "groups", scenario_groups },
		{ "connections", scenario_connections }, { "throttle", scenario_throttle },
		{ "bounds", scenario_bounds }, { "config", scenario_config },
		{ "socketdir", scenario_socketdir }, { "reserve", scenario_reserve },
	};

	for (size_t i = 0; argc == 2 && i < sizeof(scenarios) / sizeof(scenarios[0]); i++) {
		if (strcmp(argv[1], scenarios[i].name) != 0)
			continue;
		if (strcmp(argv[1], "config") != 0)
			harness_need_device();
		scenarios[i].fn();
		return test_report(argv[1]);
	}
	fprintf(stderr, "usage: test_daemon_roles roles|groups|connections|throttle|bounds|config|socketdir\n");
	return 2;
}
