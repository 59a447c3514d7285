/* log.h - the daemon's log: one line per message on stderr, with a level,
 * so that journald (which reads the "<N>" prefix) or a terminal can take it. */
#ifndef SKYD_LOG_H
#define SKYD_LOG_H

#include <stddef.h>

enum log_level { LOG_LEVEL_ERROR = 3, LOG_LEVEL_WARNING = 4, LOG_LEVEL_INFO = 6, LOG_LEVEL_DEBUG = 7 };

/* Messages above level are dropped. $SKYD_LOG (error|warning|info|debug)
 * overrides the default of info. With prefix_levels, lines start with the
 * syslog "<N>" marker (set when stderr is the journal). */
void log_init(enum log_level level, int prefix_levels);
/* Parses a level name; -EINVAL if unknown. */
int log_parse_level(const char *name, enum log_level *ret);

void log_msg(enum log_level level, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
#define log_error(...) log_msg(LOG_LEVEL_ERROR, __VA_ARGS__)
#define log_warning(...) log_msg(LOG_LEVEL_WARNING, __VA_ARGS__)
#define log_info(...) log_msg(LOG_LEVEL_INFO, __VA_ARGS__)
#define log_debug(...) log_msg(LOG_LEVEL_DEBUG, __VA_ARGS__)

/* Copies untrusted text into buf (always terminated) with every byte that
 * is not printable ASCII written as \xNN, so that a peer cannot forge lines.
 * Returns buf. */
char *log_escape(const char *text, size_t len, char *buf, size_t size);

#endif
