/* cmd.c - the command table of the text protocol (proto/PROTOCOL.md),
 * the verbs about the protocol itself (commands, help, ping, close) and
 * what the verbs share for parsing their arguments. */
#include "ctl_internal.h"

#include <errno.h>
#include <locale.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Every verb, in the order `commands` lists them. A new group of verbs
 * (cmd_*.c) adds its entries here. A verb that changes the sky or skyd
 * needs ROLE_CONTROLLER (the dispatcher refuses readers with ACK 4); view
 * decides per sub-command (list reads). */
static const struct ctl_cmd cmds[] = {
	{ "set", "set key=value ...", "change the sky; all or nothing; names the generation that shows it",
	  1, PROTO_MAX_ARGS, ctl_cmd_set, ROLE_CONTROLLER },
	{ "get", "get [key ...] | get sun | get moon | get times [date=YYYY-MM-DD] [utc_offset_min=N] | get weather | get clouds | get sensor",
	  "the current state, every key or the named ones; the clock's sun, moon, or the day's rise, set and twilights; the weather keys and what they map to; the cloud layers, the wind and the field's region; the light sensor",
	  0, PROTO_MAX_ARGS, ctl_cmd_get, ROLE_READER },
	{ "batch", "batch", "start a batch: set lines until end apply as one change (no reply until end)",
	  0, 0, ctl_cmd_batch, ROLE_CONTROLLER },
	{ "end", "end", "apply the batch as one change", 0, 0, ctl_cmd_end, ROLE_CONTROLLER },
	{ "status", "status", "generation, computation times, device, clients, last error", 0, 0, ctl_cmd_status, ROLE_READER },
	{ "subscribe", "subscribe [tables=LIST] [events=0|1]",
	  "tables: receive the shared memory (SCM_RIGHTS) and its layout; events: changed: lines",
	  1, 2, ctl_cmd_subscribe, ROLE_READER },
	{ "unsubscribe", "unsubscribe", "stop events and layout lines", 0, 0, ctl_cmd_unsubscribe, ROLE_READER },
	{ "sample", "sample sky el_deg=E az_deg=A | sample sun | sample ambient",
	  "sky radiance in a direction (no sun disk), the sun's illuminance at the observer, or the horizontal sky irradiance, from the published tables",
	  1, 3, ctl_cmd_sample, ROLE_READER },
	{ "view", "view add name=NAME [altitude_km=H] [yaw_deg=] [pitch_deg=] [roll_deg=] [vfov_deg=] [aspect=] | view del name=NAME | view list",
	  "cameras with their own aerial-perspective volume; a view lasts while the connection that added it is open",
	  1, 8, ctl_cmd_view, ROLE_READER },
	{ "sensor", "sensor list | sensor events=0|1",
	  "the USB light sensors skyd knows; events: sensor: lines on each reading and change of state",
	  1, 1, ctl_cmd_sensor, ROLE_CONTROLLER },
	{ "commands", "commands", "list the verbs", 0, 0, ctl_cmd_commands, ROLE_READER },
	{ "help", "help [VERB]", "usage of a verb", 0, 1, ctl_cmd_help, ROLE_READER },
	{ "ping", "ping", "answer OK", 0, 0, ctl_cmd_ping, ROLE_READER },
	{ "close", "close", "answer OK and close the connection", 0, 0, ctl_cmd_close, ROLE_READER },
};
static const size_t n_cmds = sizeof(cmds) / sizeof(cmds[0]);

const struct ctl_cmd *ctl_find_cmd(const char *name)
{
	for (size_t i = 0; i < n_cmds; i++)
		if (strcmp(cmds[i].name, name) == 0)
			return &cmds[i];
	return NULL;
}

int ctl_cmd_commands(struct client *c, const struct proto_request *req, struct reply *r,
		     char *msg, size_t msg_size)
{
	for (size_t i = 0; i < n_cmds; i++)
		ctl_reply_add(r, "command: %s\n", cmds[i].name);
	return 0;
}

int ctl_cmd_help(struct client *c, const struct proto_request *req, struct reply *r,
		 char *msg, size_t msg_size)
{
	const char *name = req->n_args ? req->args[0].key : "help";
	const struct ctl_cmd *e = ctl_find_cmd(name);

	if (!e || (req->n_args && req->args[0].value))
		return CTL_ACK(SKY_ACK_NO_EXIST, "%s: unknown verb", name);
	ctl_reply_add(r, "usage: %s\nhelp: %s\n", e->usage, e->help);
	return 0;
}

int ctl_cmd_ping(struct client *c, const struct proto_request *req, struct reply *r,
		 char *msg, size_t msg_size)
{
	return 0;
}

int ctl_cmd_close(struct client *c, const struct proto_request *req, struct reply *r,
		  char *msg, size_t msg_size)
{
	c->closing = 1;
	return 0;
}

