/* dump_json.c - the streaming JSON writer of dump.h, which writes the dump's
 * manifest: pretty-printed, numbers in the C locale. */
#include "dump.h"

#include <errno.h>
#include <locale.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define JSON_DEPTH_MAX 32

struct dump_json {
	FILE *f;			/* NULL: the buffer */
	char *buf;
	size_t len, cap;
	locale_t c_locale;
	int error;			/* sticky, 0 or -errno */
	int depth;			/* open containers */
	char kind[JSON_DEPTH_MAX + 1];	/* '{' or '[' per level, 1-based */
	uint32_t items[JSON_DEPTH_MAX + 1];
	bool after_key;			/* a key waits for its value */
	bool top_done;
};

static struct dump_json *json_new(FILE *f)
{
	struct dump_json *j = calloc(1, sizeof(*j));

	if (!j)
		return NULL;
	j->f = f;
	j->c_locale = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
	if (!j->c_locale || (!f && !(j->buf = calloc(1, j->cap = 256)))) {
		dump_json_free(j);
		return NULL;
	}
	return j;
}

struct dump_json *dump_json_new_file(FILE *f)
{
	return f ? json_new(f) : NULL;
}

struct dump_json *dump_json_new_buffer(void)
{
	return json_new(NULL);
}

void dump_json_free(struct dump_json *j)
{
	if (!j)
		return;
	if (j->c_locale)
		freelocale(j->c_locale);
	free(j->buf);
	free(j);
}

static int json_error(struct dump_json *j, int r)
{
	if (!j->error)
		j->error = r;
	return j->error;
}

static void json_put(struct dump_json *j, const char *s, size_t n)
{
	if (j->error)
		return;
	if (j->f) {
		if (fwrite(s, 1, n, j->f) != n)
			json_error(j, -EIO);
		return;
	}
	if (j->cap - j->len <= n) {
		size_t cap = j->cap;
		char *p;

		while (cap - j->len <= n) {
			if (cap > SIZE_MAX / 2) {
				json_error(j, -ENOMEM);
				return;
			}
			cap *= 2;
		}
		if (!(p = realloc(j->buf, cap))) {
			json_error(j, -ENOMEM);
			return;
		}
		j->buf = p;
		j->cap = cap;
	}
	memcpy(j->buf + j->len, s, n);
	j->len += n;
	j->buf[j->len] = '\0';
}

static void json_puts(struct dump_json *j, const char *s)
{
	json_put(j, s, strlen(s));
}

static void json_newline(struct dump_json *j)
{
	json_put(j, "\n", 1);
	for (int d = 0; d < j->depth; d++)
		json_put(j, "  ", 2);
}

/* Separator and indent before a value; refuses a value where none fits. */
static int json_before_value(struct dump_json *j)
{
	if (j->error)
		return j->error;
	if (j->depth == 0)
		return j->top_done ? json_error(j, -EINVAL) : 0;
	if (j->kind[j->depth] == '{') {
		if (!j->after_key)
			return json_error(j, -EINVAL);
		j->after_key = false;
		return 0;
	}
	if (j->items[j->depth]++)
		json_put(j, ",", 1);
	json_newline(j);
	return j->error;
}

static int json_after_value(struct dump_json *j)
{
	if (j->depth == 0)
		j->top_done = true;
	return j->error;
}

static void json_put_string(struct dump_json *j, const char *s)
{
	json_put(j, "\"", 1);
	for (const char *run = s;; s++) {
		unsigned char c = (unsigned char)*s;
		char esc[8];

		if (c >= 0x20 && c != '"' && c != '\\')
			continue;
		json_put(j, run, (size_t)(s - run));
		if (!c)
			break;
		switch (c) {
		case '"': json_puts(j, "\\\""); break;
		case '\\': json_puts(j, "\\\\"); break;
		case '\b': json_puts(j, "\\b"); break;
		case '\f': json_puts(j, "\\f"); break;
		case '\n': json_puts(j, "\\n"); break;
		case '\r': json_puts(j, "\\r"); break;
		case '\t': json_puts(j, "\\t"); break;
		default:
			snprintf(esc, sizeof(esc), "\\u%04x", c);
			json_puts(j, esc);
		}
		run = s + 1;
	}
	json_put(j, "\"", 1);
}

static int json_begin(struct dump_json *j, char kind)
{
	if (!j)
		return -EINVAL;
	if (json_before_value(j) < 0)
		return j->error;
	if (j->depth == JSON_DEPTH_MAX)
		return json_error(j, -EINVAL);
	json_put(j, &kind, 1);
	j->depth++;
	j->kind[j->depth] = kind;
	j->items[j->depth] = 0;
	return j->error;
}

static int json_end(struct dump_json *j, char kind)
{
	if (!j)
		return -EINVAL;
	if (j->error)
		return j->error;
	if (j->depth == 0 || j->kind[j->depth] != kind || j->after_key)
		return json_error(j, -EINVAL);
	j->depth--;
	if (j->items[j->depth + 1])
		json_newline(j);
	json_put(j, kind == '{' ? "}" : "]", 1);
	return json_after_value(j);
}

int dump_json_begin_object(struct dump_json *j)
{
	return json_begin(j, '{');
}

int dump_json_end_object(struct dump_json *j)
{
	return json_end(j, '{');
}

int dump_json_begin_array(struct dump_json *j)
{
	return json_begin(j, '[');
}

int dump_json_end_array(struct dump_json *j)
{
	return json_end(j, '[');
}

int dump_json_key(struct dump_json *j, const char *key)
{
	if (!j)
		return -EINVAL;
	if (j->error)
		return j->error;
	if (!key || j->depth == 0 || j->kind[j->depth] != '{' || j->after_key)
		return json_error(j, -EINVAL);
	if (j->items[j->depth]++)
		json_put(j, ",", 1);
	json_newline(j);
	json_put_string(j, key);
	json_put(j, ": ", 2);
	j->after_key = true;
	return j->error;
}

/* A scalar already formatted; NULL text is a misuse. */
static int json_scalar(struct dump_json *j, const char *text)
{
	if (!j)
		return -EINVAL;
	if (!text)
		return json_error(j, -EINVAL);
	if (json_before_value(j) < 0)
		return j->error;
	json_puts(j, text);
	return json_after_value(j);
}

int dump_json_string(struct dump_json *j, const char *s)
{
	if (!j)
		return -EINVAL;
	if (!s)
		return json_error(j, -EINVAL);
	if (json_before_value(j) < 0)
		return j->error;
	json_put_string(j, s);
	return json_after_value(j);
}

int dump_json_number(struct dump_json *j, double x)
{
	char text[32];
	locale_t old;

	if (!j)
		return -EINVAL;
	if (!isfinite(x))
		return json_scalar(j, "null");
	old = uselocale(j->c_locale);
	snprintf(text, sizeof(text), "%.17g", x);
	uselocale(old);
	return json_scalar(j, text);
}

int dump_json_uint(struct dump_json *j, uint64_t x)
{
	char text[24];

	snprintf(text, sizeof(text), "%llu", (unsigned long long)x);
	return json_scalar(j, text);
}

int dump_json_bool(struct dump_json *j, bool b)
{
	return json_scalar(j, b ? "true" : "false");
}

int dump_json_null(struct dump_json *j)
{
	return json_scalar(j, "null");
}

int dump_json_finish(struct dump_json *j)
{
	if (!j)
		return -EINVAL;
	if (j->error)
		return j->error;
	if (j->depth != 0 || !j->top_done)
		return json_error(j, -EINVAL);
	json_put(j, "\n", 1);
	if (j->f && fflush(j->f) != 0)
		json_error(j, -errno);
	return j->error;
}

const char *dump_json_buffer(const struct dump_json *j, size_t *ret_len)
{
	if (!j || j->f)
		return NULL;
	if (ret_len)
		*ret_len = j->len;
	return j->buf;
}
