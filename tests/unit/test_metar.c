/* test_metar.c - the METAR decoder against the corpus in tests/data/metar
 * (every report's expected values, every refusal's group and position),
 * plus edge cases and a seeded mutation run that must never misbehave. */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "metar.h"
#include "state.h"
#include "test.h"

#define MAX_PAIRS 96

struct pairs {
	int n;
	char key[MAX_PAIRS][48];
	char value[MAX_PAIRS][METAR_MAX_LEN];
};

static void collect(void *ctx, const char *key, const char *value)
{
	struct pairs *p = ctx;
	if (p->n == MAX_PAIRS) {
		FAIL("more than %d pairs", MAX_PAIRS);
		return;
	}
	snprintf(p->key[p->n], sizeof(p->key[0]), "%s", key);
	snprintf(p->value[p->n], sizeof(p->value[0]), "%s", value);
	p->n++;
}

static const char *lookup(const struct pairs *p, const char *key)
{
	for (int i = 0; i < p->n; i++)
		if (strcmp(p->key[i], key) == 0)
			return p->value[i];
	return NULL;
}

static char *trim(char *s)
{
	while (*s == ' ' || *s == '\t')
		s++;
	size_t n = strlen(s);
	while (n && strchr(" \t\r\n", s[n - 1]))
		s[--n] = '\0';
	return s;
}

/* A number matches to the precision it is written with; "0.41" accepts
 * 0.405 to 0.415. Anything else must be equal. */
static bool value_matches(const char *want, const char *got)
{
	char *end1, *end2;
	double w = strtod(want, &end1), g = strtod(got, &end2);
	if (*want && *got && !*end1 && !*end2 && end1 != want && end2 != got) {
		const char *dot = strchr(want, '.');
		int decimals = dot ? (int)strlen(dot + 1) : 0;
		return fabs(w - g) <= 0.5 * pow(10.0, -decimals) * (1.0 + 1e-9);
	}
	return strcmp(want, got) == 0;
}

/* Checks one "key=value; ..." expectation against a report. Returns true
 * for an accepted report, false for a refused one. */
static bool check_report(const char *report, char *expect, int line)
{
	struct metar m;
	struct pairs got = { 0 };
	char err[256] = "";
	int rc = metar_decode(report, &m, err, sizeof(err));
	bool refusal = strstr(expect, "error_position=") != NULL;

	if (refusal) {
		char pos[16];
		snprintf(pos, sizeof(pos), "%d", m.error_position);
		collect(&got, "error_position", pos);
		collect(&got, "error_group", m.error_group);
		if (rc != -EINVAL)
			FAIL("line %d: accepted a malformed report", line);
		/* The message names the group and its position. */
		char head[64];
		snprintf(head, sizeof(head), "group %d '%s'", m.error_position, m.error_group);
		if (!strstr(err, head))
			FAIL("line %d: message '%s' does not start with %s", line, err, head);
	} else {
		if (rc != 0) {
			FAIL("line %d: refused: %s", line, err);
			return true;
		}
		struct weather w;
		weather_init(&w);
		metar_weather(&m, &w);
		metar_describe(&m, collect, &got);
		/* The inputs under their keys: the first lines of get weather. */
		struct sky_state st;
		state_default(&st);
		st.weather.in = w;
		if (state_describe_weather(&st, collect, &got, err, sizeof(err)) < 0)
			FAIL("line %d: %s", line, err);
	}
	for (char *save, *item = strtok_r(expect, ";", &save); item;
	     item = strtok_r(NULL, ";", &save)) {
		char *eq = strchr(item, '=');
		if (!eq) {
			FAIL("line %d: '%s' is not key=value", line, item);
			continue;
		}
		*eq = '\0';
		const char *key = trim(item), *want = trim(eq + 1), *have = lookup(&got, key);
		test_checks++;
		if (!have)
			FAIL("line %d: no key '%s'", line, key);
		else if (!value_matches(want, have))
			FAIL("line %d: %s is '%s', expected '%s'", line, key, have, want);
	}
	return !refusal;
}

static void test_corpus(void)
{
	char path[512], buf[2][2048];
	snprintf(path, sizeof(path), "%s/metar/corpus.txt", SKYD_TEST_DATA);
	FILE *f = fopen(path, "r");
	int line = 0, accepted = 0, refused = 0, report_line = 0;
	bool have_report = false;

	if (!f) {
		FAIL("cannot open %s", path);
		return;
	}
	while (fgets(buf[1], sizeof(buf[1]), f)) {
		line++;
		char *s = trim(buf[1]);
		if (!*s || *s == '#')
			continue;
		if (*s == '>') {
			if (!have_report) {
				FAIL("line %d: expectation without a report", line);
				continue;
			}
			if (check_report(buf[0], s + 1, report_line))
				accepted++;
			else
				refused++;
			have_report = false;
			continue;
		}
		if (have_report)
			FAIL("line %d: report without an expectation", report_line);
		memmove(buf[0], s, strlen(s) + 1);
		report_line = line;
		have_report = true;
	}
	fclose(f);
	if (have_report)
		FAIL("line %d: report without an expectation", report_line);
	printf("corpus: %d reports decoded, %d refused as expected\n", accepted, refused);
	CHECK(accepted >= 40);
	CHECK(refused >= 10);
}

static void test_edges(void)
{
	struct metar m;
	char err[256], big[METAR_MAX_LEN + 16];

	CHECK(metar_decode("", &m, err, sizeof(err)) == -EINVAL);
	CHECK(metar_decode("   =", &m, err, sizeof(err)) == -EINVAL);
	memset(big, 'A', sizeof(big) - 1);
	big[sizeof(big) - 1] = '\0';
	CHECK(metar_decode(big, &m, err, sizeof(err)) == -EINVAL);
	/* No type word: a bare report is a METAR. */
	CHECK(metar_decode("EGLL 121250Z 24015KT 9999 FEW030 15/09 Q1012", &m, err,
			   sizeof(err)) == 0);
	CHECK(strcmp(m.type, "METAR") == 0 && m.qnh_hpa == 1012.0);
	CHECK(metar_cover_oktas(METAR_FEW) == 1.5 && metar_cover_oktas(METAR_OVC) == 8.0);
	CHECK(isnan(metar_cover_oktas(METAR_COVER_MISSING)));
	/* A METAR leaves turbidity and ozone to the caller. */
	struct weather w;
	weather_init(&w);
	w.ozone_du = 320.0;
	w.angstrom_beta = 0.2;
	w.visibility_km = 3.0;
	CHECK(metar_decode("METAR EGLL 121250Z 24015KT CAVOK 15/09 Q1012", &m, err,
			   sizeof(err)) == 0);
	metar_weather(&m, &w);
	CHECK(w.ozone_du == 320.0 && w.angstrom_beta == 0.2 && isnan(w.visibility_km));
	CHECK(w.cloud_oktas == 0.0);
}

static uint64_t next(uint64_t *s)
{
	*s = *s * 6364136223846793005ull + 1442695040888963407ull;
	return *s >> 33;
}

/* Corrupted reports: every outcome is 0 or -EINVAL with a position inside
 * the report, and a decoded one maps to weather inputs in their ranges. */
static void test_mutations(void)
{
	static const char *const seeds[] = {
		"SPECI KORD 031422Z 05018G29KT 1/2SM R28L/2600FT +SN FZFG VV004 M04/M05 A2965 RMK AO2",
		"METAR EHAM 121325Z 22015G27KT 190V260 4000 -RA BR BKN008 OVC012 14/13 Q1003 RERA",
		"METAR KDEN 121553Z 16006KT 1 3/4SM -FZDZ BR OVC004 M01/M02 A3021 RMK AO2",
	};
	static const char alphabet[] = "0123456789/ABCGKMNPQRSTVZ+- ";
	uint64_t seed = 7;
	char s[METAR_MAX_LEN], err[256];
	struct metar m;

	for (int i = 0; i < 20000; i++) {
		snprintf(s, sizeof(s), "%s", seeds[i % 3]);
		size_t n = strlen(s);
		for (int k = 0, edits = 1 + (int)(next(&seed) % 4); k < edits; k++)
			s[next(&seed) % n] = alphabet[next(&seed) % (sizeof(alphabet) - 1)];
		int groups = 0;
		for (char *p = s; *p;) {
			p += strspn(p, " ");
			if (*p)
				groups++;
			p += strcspn(p, " ");
		}
		int rc = metar_decode(s, &m, err, sizeof(err));
		if (rc == 0) {
			struct weather w;
			weather_init(&w);
			metar_weather(&m, &w);
			if (weather_validate(&w, err, sizeof(err)) < 0)
				FAIL("'%s': %s", s, err);
		} else if (rc != -EINVAL || m.error_position < 1 || m.error_position > groups) {
			FAIL("'%s': rc %d position %d of %d", s, rc, m.error_position, groups);
		}
	}
}

int main(void)
{
	test_corpus();
	test_edges();
	test_mutations();
	return test_report("test_metar");
}
