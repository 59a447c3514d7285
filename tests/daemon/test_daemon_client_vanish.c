/* test_daemon_client_vanish.c - clients that vanish during their own command: a
 * subscriber that sends a set and closes without reading is dropped by the
 * very publication its set causes, while skyd is still inside that set.
 * skyd must go on serving (under the sanitizers: without a report). */
#include "daemon_harness.h"
#include "test.h"

/* Opens a connection, then, while skyd is stopped, sends text and closes
 * without reading a byte: when skyd runs again it finds the lines and a
 * peer that is gone, so its first write to it fails in the middle of the
 * last verb. Stopping skyd makes the order certain, not a race. */
static int send_and_vanish(const struct daemon *d, const char *text)
{
	struct conn c;
	int status, ok;

	if (conn_open(&c, d->sock) < 0)
		return -1;
	kill(d->pid, SIGSTOP);
	ok = waitpid(d->pid, &status, WUNTRACED) == d->pid && WIFSTOPPED(status);
	ok = ok && send(c.fd, text, strlen(text), MSG_NOSIGNAL) == (ssize_t)strlen(text);
	conn_close(&c);
	kill(d->pid, SIGCONT);
	ok = ok && waitpid(d->pid, &status, WCONTINUED) == d->pid && WIFCONTINUED(status);
	return ok ? 0 : -1;
}

static int log_count(const struct daemon *d, const char *needle)
{
	char line[1024];
	int n = 0;
	FILE *f = fopen(d->log, "re");

	while (f && fgets(line, sizeof(line), f))
		n += strstr(line, needle) != NULL;
	if (f)
		fclose(f);
	return n;
}

/* skyd answers ping on a new connection and its process is alive. */
static int still_serving(const struct daemon *d)
{
	struct conn c;
	char reply[256];
	int ok = conn_open(&c, d->sock) == 0 && conn_request(&c, "ping", reply, sizeof(reply)) == 0;

	conn_close(&c);
	return ok && waitpid(d->pid, NULL, WNOHANG) == 0;
}

int main(void)
{
	const char *args[] = { HARNESS_SMALL, NULL };
	/* The lines from the report that found it, then the same with a batch
	 * and a view: each verb that changes the sky publishes while it runs. */
	static const char *const scripts[] = {
		"subscribe events=1\nset sun_elevation_deg=%d\n",
		"subscribe events=1\nbatch\nset sun_elevation_deg=%d\nset ground_albedo=0.2\nend\n",
		"subscribe events=1\nset sun_azimuth_deg=%d\nset sun_elevation_deg=5\n",
		"subscribe events=1\nview add name=v%d vfov_deg=50\nset camera_yaw_deg=10\n",
	};
	struct daemon d = { 0 };
	char text[256];

	harness_need_device();
	if (daemon_start(&d, args) < 0)
		return 1;
	for (int round = 0; round < 40 && !test_failures; round++) {
		snprintf(text, sizeof(text), scripts[round % 4], 1 + round);
		CHECK(send_and_vanish(&d, text) == 0);
		CHECK(still_serving(&d));
	}
	/* Each of them was dropped by a failed write, not by its own EOF. */
	CHECK(log_count(&d, "dropped: Broken pipe") >= 40);
	CHECK(still_serving(&d));
	int status = daemon_stop(&d, SIGTERM);
	CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
	if (test_failures) {
		snprintf(text, sizeof(text), "cat '%s' >&2", d.log);
		(void)!system(text);
	}
	daemon_cleanup(&d);
	return test_report("test_daemon_client_vanish");
}
