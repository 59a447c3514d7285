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

#endif
