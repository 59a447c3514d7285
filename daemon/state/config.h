/* config.h - the daemon's configuration file: "key = value" lines with the
 * keys of the protocol's set verb, '#' comments and blank lines. A value is
 * the rest of the line, spaces kept (metar = EGLL 241250Z ...); double
 * quotes around it are dropped. */
#ifndef SKYD_CONFIG_H
#define SKYD_CONFIG_H

#include <stddef.h>

#include "state.h"

/* Applies the file at path to s as one change: on any error s is left
 * untouched and err holds "path:line: key: message". Returns 0 or -errno
 * (-EINVAL for a bad line or a state that fails state_validate). */
int config_load(const char *path, struct sky_state *s, char *err, size_t err_size);

/* The daemon's own settings among the lines (sync=, sync_role=, ...: they
 * configure this process, they are not the sky's state): 1 when key is
 * one of them and value was taken, 0 when key is not one (it goes to the
 * state), -errno with err when value is refused. */
typedef int config_key_fn(void *ctx, const char *key, const char *value, char *err,
			  size_t err_size);
/* config_load, handing each key to daemon_key first (NULL: none). What
 * daemon_key took stays taken when a later line fails. */
int config_load_with(const char *path, struct sky_state *s, config_key_fn *daemon_key, void *ctx,
		     char *err, size_t err_size);

#endif
