/* metar.c - METAR/SPECI decoding, group by group in the order the code
 * form fixes, and the report's mapping onto weather inputs. */
#include "metar.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <regex.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "skycloud.h"

#define MAX_TOKENS 128
#define SM_TO_M 1609.344
#define INHG_TO_HPA 33.8639	/* hPa per inch of mercury */

/* The groups in the order of the code form; a report's groups must come in
 * this order, those marked repeat may come several times. */
enum group {
	G_TYPE, G_COR, G_STATION, G_TIME, G_NIL, G_MOD, G_WIND, G_WIND_VAR, G_VIS, G_VIS_MIN,
	G_RVR, G_WX, G_CLOUD, G_TEMP, G_PRESSURE, G_SUPP, G_N,
};

static const struct {
	const char *re;		/* POSIX extended, anchored */
	bool repeat, mandatory, used;
	const char *what;
} groups[G_N] = {
	[G_TYPE] = { "^(METAR|SPECI)$", false, false, false, "report type" },
	[G_COR] = { "^COR$", false, false, false, "correction" },
	[G_STATION] = { "^[A-Z][A-Z0-9]{3}$", false, true, false, "station (4 letters or digits)" },
	[G_TIME] = { "^([0-9]{2})([0-9]{2})([0-9]{2})Z$", false, true, false, "time (DDHHMMZ)" },
	[G_NIL] = { "^NIL$", false, false, false, "NIL" },
	[G_MOD] = { "^(AUTO|COR|CC[A-Z]|RTD)$", true, false, false, "AUTO or COR" },
	[G_WIND] = { "^([0-9]{3}|VRB|///)P?([0-9]{2,3}|//)(GP?([0-9]{2,3}))?(KT|MPS|KMH)$",
		     false, false, true, "wind" },
	[G_WIND_VAR] = { "^([0-9]{3})V([0-9]{3})$", false, false, false, "wind sector" },
	[G_VIS] = { "^(([0-9]{4})(NDV)?|CAVOK|////(SM)?|([PM]?)([0-9]{1,2})SM|"
		    "([PM]?)([0-9])/([0-9]{1,2})SM)$", false, false, true, "visibility" },
	[G_VIS_MIN] = { "^([0-9]{4})(N|NE|E|SE|S|SW|W|NW)$", false, false, true,
			"minimum visibility" },
	[G_RVR] = { "^R[0-9]{2}[LCR]?/([PM]?[0-9]{4}(V[PM]?[0-9]{4})?(FT)?(/?[UDN])?|/{4,})$",
		    true, false, false, "runway visual range" },
	[G_WX] = { "^(NSW|//|(\\+|-|VC)?(MI|BC|PR|DR|BL|SH|TS|FZ)?"
		   "((DZ|RA|SN|SG|IC|PL|GR|GS|UP|BR|FG|FU|VA|DU|SA|HZ|PY|PO|SQ|FC|SS|DS)*))$",
		   true, false, true, "present weather" },
	[G_CLOUD] = { "^((FEW|SCT|BKN|OVC|///)([0-9]{3}|///)(CB|TCU|///)?|SKC|CLR|NSC|NCD|"
		      "VV([0-9]{3}|///))$", true, false, true, "cloud" },
	[G_TEMP] = { "^(M?[0-9]{2}|//)/(M?[0-9]{2}|//)?$", false, false, true,
		     "temperature/dew point" },
	[G_PRESSURE] = { "^(Q|A)([0-9]{4}|////)$", true, false, true, "pressure" },
	[G_SUPP] = { "^(RE(\\+|-|VC)?[A-Z]{2,8}|WS|W(M?[0-9]{2}|//)/[SH][0-9/]{1,3}|"
		     "R[0-9]{2}[LCR]?/[0-9/]{6}|R/?SNOCLO|SNOCLO)$", true, false, false,
		     "supplementary" },
};

static const char *const phenomenon_codes[] = {
	"DZ", "RA", "SN", "SG", "IC", "PL", "GR", "GS", "UP", "BR", "FG",
	"FU", "VA", "DU", "SA", "HZ", "PY", "PO", "SQ", "FC", "SS", "DS", NULL,
};

/* The grammar, compiled once for the process; regexec only reads it. */
static regex_t grammar[G_N];
static bool grammar_ok;
static pthread_once_t grammar_once = PTHREAD_ONCE_INIT;

static void compile_grammar(void)
{
	for (int g = 0; g < G_N; g++)
		if (regcomp(&grammar[g], groups[g].re, REG_EXTENDED) != 0)
			return;
	grammar_ok = true;
}

/* What a decode works on: the report's groups and the report being filled. */
struct decoder {
	char buf[METAR_MAX_LEN];
	char *tok[MAX_TOKENS];
	int n;
	struct metar *m;
	char *err;
	size_t err_size;
};

static int fail(struct decoder *d, int i, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int fail(struct decoder *d, int i, const char *fmt, ...)
{
	char why[160];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(why, sizeof(why), fmt, ap);
	va_end(ap);
	d->m->error_position = i + 1;
	snprintf(d->m->error_group, sizeof(d->m->error_group), "%s", d->tok[i]);
	snprintf(d->err, d->err_size, "group %d '%s': %s", i + 1, d->tok[i], why);
	return -EINVAL;
}

static void append(char *list, const char *group)
{
	size_t n = strlen(list);
	if (n + strlen(group) + 2 > METAR_MAX_LEN)
		return;
	snprintf(list + n, METAR_MAX_LEN - n, "%s%s", n ? " " : "", group);
}

static void note(struct decoder *d, int i, bool used)
{
	append(used ? d->m->used : d->m->ignored, d->tok[i]);
}

/* Integer of the sub-match k, or -1 when it did not take part. */
static int sub_int(const char *s, const regmatch_t *pm, int k)
{
	if (pm[k].rm_so < 0 || pm[k].rm_eo == pm[k].rm_so)
		return -1;
	char b[16];
	int len = (int)(pm[k].rm_eo - pm[k].rm_so);
	if (len >= (int)sizeof(b) || !strchr("0123456789", s[pm[k].rm_so]))
		return -1;
	snprintf(b, sizeof(b), "%.*s", len, s + pm[k].rm_so);
	return atoi(b);
}

static bool sub_is(const char *s, const regmatch_t *pm, int k, const char *text)
{
	size_t len = pm[k].rm_so < 0 ? 0 : (size_t)(pm[k].rm_eo - pm[k].rm_so);
	return pm[k].rm_so >= 0 && len == strlen(text) && strncmp(s + pm[k].rm_so, text, len) == 0;
}

/* Temperature "M05" -> -5; NAN for "//" or absent. */
static double sub_temp(const char *s, const regmatch_t *pm, int k)
{
	if (pm[k].rm_so < 0 || s[pm[k].rm_so] == '/' || pm[k].rm_eo == pm[k].rm_so)
		return NAN;
	bool minus = s[pm[k].rm_so] == 'M';
	double t = atoi(s + pm[k].rm_so + (minus ? 1 : 0));
	return minus ? -t : t;
}

static int read_time(struct decoder *d, int i, const regmatch_t *pm)
{
	const char *s = d->tok[i];
	int day = sub_int(s, pm, 1), hour = sub_int(s, pm, 2), minute = sub_int(s, pm, 3);
	if (day < 1 || day > 31 || hour > 23 || minute > 59)
		return fail(d, i, "day 01-31, hour 00-23, minute 00-59");
	d->m->day = day;
	d->m->hour = hour;
	d->m->minute = minute;
	return 0;
}

static int read_wind(struct decoder *d, int i, const regmatch_t *pm)
{
	const char *s = d->tok[i];
	struct metar *m = d->m;
	int dir = sub_int(s, pm, 1);

	if (dir > 360)
		return fail(d, i, "wind direction above 360 degrees");
	m->wind_variable = sub_is(s, pm, 1, "VRB");
	m->wind_dir_deg = dir >= 0 ? dir : NAN;
	int speed = sub_int(s, pm, 2), gust = sub_int(s, pm, 4);
	m->wind_speed = speed >= 0 ? speed : NAN;
	m->wind_gust = gust >= 0 ? gust : NAN;
	snprintf(m->wind_unit, sizeof(m->wind_unit), "%.*s", (int)(pm[5].rm_eo - pm[5].rm_so),
		 s + pm[5].rm_so);
	return 0;
}

static int read_wind_var(struct decoder *d, int i, const regmatch_t *pm)
{
	int from = sub_int(d->tok[i], pm, 1), to = sub_int(d->tok[i], pm, 2);
	if (from > 360 || to > 360)
		return fail(d, i, "wind sector bound above 360 degrees");
	d->m->wind_from_deg = from;
	d->m->wind_to_deg = to;
	return 0;
}

/* Prevailing visibility; whole_sm >= 0 is the whole part of a "1 1/2SM"
 * pair read as two groups. */
static int read_vis(struct decoder *d, int i, const regmatch_t *pm, int whole_sm)
{
	const char *s = d->tok[i];
	struct metar *m = d->m;
	int metres = sub_int(s, pm, 2);

	m->visibility_qualifier = METAR_EXACT;
	if (strcmp(s, "CAVOK") == 0) {
		m->cavok = true;
		m->sky = METAR_SKY_CLEAR;
		m->visibility_m = 10000.0;
		m->visibility_qualifier = METAR_OR_MORE;
	} else if (s[0] == '/') {
		m->visibility_m = NAN;
	} else if (metres >= 0) {
		m->visibility_m = metres == 0 ? 50.0 : metres;
		if (metres == 9999)
			m->visibility_m = 10000.0;
		m->visibility_qualifier = metres == 9999 ? METAR_OR_MORE
					  : metres == 0 ? METAR_LESS_THAN : METAR_EXACT;
	} else {
		/* Statute miles: "P6SM", "10SM", "M1/4SM", "1/2SM", "1 1/2SM". */
		bool fraction = pm[8].rm_so >= 0;
		int pk = fraction ? 7 : 5;
		double sm = fraction ? sub_int(s, pm, 8) : sub_int(s, pm, 6);
		if (fraction) {
			int den = sub_int(s, pm, 9);
			if (den <= 0 || sm >= den)
				return fail(d, i, "a fraction of a mile needs 0 < numerator < denominator");
			sm = sm / den + (whole_sm > 0 ? whole_sm : 0);
		}
		m->visibility_m = sm * SM_TO_M;
		/* 10SM is the most the US reports: "10 miles or more". */
		if (sub_is(s, pm, pk, "P") || (!fraction && sm == 10.0 && whole_sm < 0))
			m->visibility_qualifier = METAR_OR_MORE;
		else if (sub_is(s, pm, pk, "M"))
			m->visibility_qualifier = METAR_LESS_THAN;
	}
	return 0;
}

static int read_vis_min(struct decoder *d, int i, const regmatch_t *pm)
{
	const char *s = d->tok[i];
	d->m->min_visibility_m = sub_int(s, pm, 1);
	snprintf(d->m->min_visibility_dir, sizeof(d->m->min_visibility_dir), "%.*s",
		 (int)(pm[2].rm_eo - pm[2].rm_so), s + pm[2].rm_so);
	return 0;
}

static int read_weather(struct decoder *d, int i, const regmatch_t *pm)
{
	const char *s = d->tok[i];
	struct metar *m = d->m;

	if (strcmp(s, "NSW") == 0) {
		m->no_significant_weather = true;
		return 0;
	}
	if (strcmp(s, "//") == 0)
		return 0;
	/* Sub-matches: 2 intensity, 3 descriptor, 4 the phenomena. */
	if (pm[3].rm_so < 0 && pm[4].rm_eo == pm[4].rm_so)
		return fail(d, i, "present weather needs a descriptor or a phenomenon");
	if (m->n_weather == METAR_MAX_WEATHER)
		return fail(d, i, "more than %d present weather groups", METAR_MAX_WEATHER);
	struct metar_weather_group *g = &m->weather[m->n_weather++];
	*g = (struct metar_weather_group){ 0 };
	snprintf(g->code, sizeof(g->code), "%s", s);
	g->intensity = sub_is(s, pm, 2, "-") ? -1 : sub_is(s, pm, 2, "+") ? 1 : 0;
	g->vicinity = sub_is(s, pm, 2, "VC");
	if (pm[3].rm_so >= 0)
		snprintf(g->descriptor, sizeof(g->descriptor), "%.2s", s + pm[3].rm_so);
	for (regoff_t k = pm[4].rm_so; k + 1 < pm[4].rm_eo; k += 2)
		for (int c = 0; phenomenon_codes[c]; c++)
			if (strncmp(s + k, phenomenon_codes[c], 2) == 0)
				g->phenomena |= 1u << c;
	return 0;
}

static int read_cloud(struct decoder *d, int i, const regmatch_t *pm)
{
	static const char *const covers[] = { "///", "FEW", "SCT", "BKN", "OVC" };
	const char *s = d->tok[i];
	struct metar *m = d->m;

	/* Sub-matches: 2 cover, 3 height, 4 type, 5 vertical visibility. */
	if (strncmp(s, "VV", 2) == 0) {
		int h = sub_int(s, pm, 5);
		m->sky = METAR_SKY_OBSCURED;
		m->vertical_visibility_ft = h >= 0 ? h * 100.0 : NAN;
		return 0;
	}
	if (pm[2].rm_so < 0) {	/* SKC, CLR, NSC, NCD */
		m->sky = METAR_SKY_CLEAR;
		return 0;
	}
	if (m->n_clouds == METAR_MAX_CLOUDS)
		return fail(d, i, "more than %d cloud layers", METAR_MAX_CLOUDS);
	struct metar_cloud *c = &m->clouds[m->n_clouds++];
	*c = (struct metar_cloud){ .cover = METAR_COVER_MISSING, .height_ft = NAN };
	for (int k = 1; k <= 4; k++)
		if (sub_is(s, pm, 2, covers[k]))
			c->cover = (enum metar_cover)k;
	int h = sub_int(s, pm, 3);
	if (h >= 0)
		c->height_ft = h * 100.0;
	if (sub_is(s, pm, 4, "CB") || sub_is(s, pm, 4, "TCU"))
		snprintf(c->type, sizeof(c->type), "%.*s", (int)(pm[4].rm_eo - pm[4].rm_so),
			 s + pm[4].rm_so);
	return 0;
}

static int read_temp(struct decoder *d, int i, const regmatch_t *pm)
{
	d->m->temperature_c = sub_temp(d->tok[i], pm, 1);
	d->m->dewpoint_c = sub_temp(d->tok[i], pm, 2);
	return 0;
}

static int read_pressure(struct decoder *d, int i, const regmatch_t *pm)
{
	const char *s = d->tok[i];
	int v = sub_int(s, pm, 2);
	if (v < 0)
		return 0;
	double hpa = s[0] == 'Q' ? v : v / 100.0 * INHG_TO_HPA;
	if (hpa < 850.0 || hpa > 1100.0)
		return fail(d, i, "pressure %.1f hPa is outside 850-1100", hpa);
	/* The first pressure group wins; Q and A of one report agree. */
	if (isnan(d->m->qnh_hpa))
		d->m->qnh_hpa = hpa;
	return 0;
}

/* Supplementary groups: recent weather, wind shear (with the runway words
 * that follow it), sea state, runway state. Returns the groups consumed. */
static int read_supp(struct decoder *d, int i)
{
	const char *s = d->tok[i];
	int used = 1;

	if (strncmp(s, "RE", 2) == 0) {
		d->m->n_recent++;
	} else if (strcmp(s, "WS") == 0) {
		d->m->wind_shear = true;
		while (i + used < d->n && used < 3 &&
		       (strcmp(d->tok[i + used], "ALL") == 0 || strncmp(d->tok[i + used], "RWY", 3) == 0 ||
			(d->tok[i + used][0] == 'R' && strlen(d->tok[i + used]) <= 4 &&
			 strchr("0123456789", d->tok[i + used][1]))))
			used++;
	}
	return used;
}

static int read_group(struct decoder *d, enum group g, int i, const regmatch_t *pm, int extra)
{
	switch (g) {
	case G_TYPE: snprintf(d->m->type, sizeof(d->m->type), "%s", d->tok[i]); return 0;
	case G_COR: d->m->corrected = true; return 0;
	case G_STATION: snprintf(d->m->station, sizeof(d->m->station), "%s", d->tok[i]); return 0;
	case G_TIME: return read_time(d, i, pm);
	case G_NIL: d->m->nil = true; return 0;
	case G_MOD:
		if (strcmp(d->tok[i], "AUTO") == 0)
			d->m->automatic = true;
		else if (strcmp(d->tok[i], "RTD") != 0)
			d->m->corrected = true;
		return 0;
	case G_WIND: return read_wind(d, i, pm);
	case G_WIND_VAR: return read_wind_var(d, i, pm);
	case G_VIS: return read_vis(d, i, pm, extra);
	case G_VIS_MIN: return read_vis_min(d, i, pm);
	case G_RVR: d->m->n_rvr++; return 0;
	case G_WX: return read_weather(d, i, pm);
	case G_CLOUD: return read_cloud(d, i, pm);
	case G_TEMP: return read_temp(d, i, pm);
	case G_PRESSURE: return read_pressure(d, i, pm);
	default: return 0;
	}
}

static bool matches(enum group g, const char *s, regmatch_t *pm)
{
	return regexec(&grammar[g], s, 10, pm, 0) == 0;
}

/* "1 1/2SM": a whole number of miles, then its fraction as the next group. */
static bool miles_pair(struct decoder *d, int i)
{
	const char *s = d->tok[i];
	size_t n = strlen(s);
	if (i + 1 >= d->n || n < 1 || n > 2 || strspn(s, "0123456789") != n)
		return false;
	const char *f = d->tok[i + 1];
	return strchr(f, '/') && strstr(f, "SM") && f[0] != 'M' && f[0] != 'P';
}

static bool stops(const char *s)
{
	return strcmp(s, "NOSIG") == 0 || strcmp(s, "BECMG") == 0 || strcmp(s, "TEMPO") == 0 ||
	       strcmp(s, "RMK") == 0;
}

/* The error for group i that no group at or after stage cur accepts; last
 * is the kind of the group before it. */
static int refuse(struct decoder *d, int i, enum group cur, enum group last)
{
	regmatch_t pm[10];
	for (enum group g = G_WIND; g < cur; g++)
		if (matches(g, d->tok[i], pm))
			return fail(d, i, "a %s group out of its place (after a %s group)",
				    groups[g].what, groups[last].what);
	if (cur <= G_STATION)
		return fail(d, i, "expected a %s", groups[G_STATION].what);
	if (cur <= G_TIME)
		return fail(d, i, "expected a %s", groups[G_TIME].what);
	return fail(d, i, "not a METAR group here (expected %s or later)", groups[cur].what);
}

/* Groups i.. from stage cur on, until a trend, RMK or the end. */
static int decode_body(struct decoder *d)
{
	enum group cur = G_TYPE, last = G_TYPE;
	regmatch_t pm[10];

	for (int i = 0; i < d->n;) {
		const char *s = d->tok[i];
		if (cur > G_TIME && stops(s)) {
			if (strcmp(s, "RMK") == 0)
				d->m->remarks = true;
			else
				snprintf(d->m->trend, sizeof(d->m->trend), "%s", s);
			for (; i < d->n; i++)
				note(d, i, false);
			return 0;
		}
		if (d->m->nil) {
			note(d, i++, false);
			continue;
		}
		int whole = -1, span = 1;
		if (cur <= G_VIS && cur > G_TIME && miles_pair(d, i)) {
			whole = atoi(s);
			i++;
			span = 2;
		}
		enum group g = cur;
		for (; g < G_N; g++) {
			if (matches(g, d->tok[i], pm))
				break;
			if (groups[g].mandatory || (whole >= 0 && g == G_VIS))
				g = G_N - 1;	/* nothing past a missing mandatory group */
		}
		if (g == G_N)
			return refuse(d, i, cur, last);
		int rc = read_group(d, g, i, pm, whole);
		if (rc < 0)
			return rc;
		if (g == G_SUPP)
			span = read_supp(d, i);
		for (int k = i - (whole >= 0 ? 1 : 0); k < i + (g == G_SUPP ? span : 1); k++)
			note(d, k, groups[g].used);
		i += g == G_SUPP ? span : 1;
		last = g;
		cur = groups[g].repeat ? g : g + 1;
	}
	if (cur <= G_TIME)
		return fail(d, d->n - 1, "the report ends before its %s",
			    groups[cur <= G_STATION ? G_STATION : G_TIME].what);
	return 0;
}

static void metar_reset(struct metar *m)
{
	*m = (struct metar){
		.wind_dir_deg = NAN, .wind_speed = NAN, .wind_gust = NAN, .wind_from_deg = -1,
		.wind_to_deg = -1, .visibility_m = NAN, .min_visibility_m = NAN,
		.vertical_visibility_ft = NAN, .temperature_c = NAN, .dewpoint_c = NAN,
		.qnh_hpa = NAN,
	};
	snprintf(m->type, sizeof(m->type), "METAR");
}

static int tokenize(struct decoder *d, const char *text)
{
	size_t len = strlen(text);
	if (len >= sizeof(d->buf)) {
		snprintf(d->err, d->err_size, "report longer than %d bytes", METAR_MAX_LEN - 1);
		return -EINVAL;
	}
	memcpy(d->buf, text, len + 1);
	/* The end-of-report '=' may be glued to the last group. */
	char *eq = strrchr(d->buf, '=');
	if (eq && strspn(eq + 1, " \t\r\n") == strlen(eq + 1))
		*eq = '\0';
	for (char *save, *t = strtok_r(d->buf, " \t\r\n", &save); t;
	     t = strtok_r(NULL, " \t\r\n", &save)) {
		if (d->n == MAX_TOKENS) {
			snprintf(d->err, d->err_size, "more than %d groups", MAX_TOKENS);
			return -EINVAL;
		}
		d->tok[d->n++] = t;
	}
	if (d->n == 0) {
		snprintf(d->err, d->err_size, "empty report");
		return -EINVAL;
	}
	return 0;
}

int metar_decode(const char *text, struct metar *ret, char *err, size_t err_size)
{
	metar_reset(ret);
	pthread_once(&grammar_once, compile_grammar);
	if (!grammar_ok) {
		snprintf(err, err_size, "internal: a METAR pattern does not compile");
		return -ENOMEM;
	}
	struct decoder *d = calloc(1, sizeof(*d));
	if (!d)
		return -ENOMEM;
	d->m = ret;
	d->err = err;
	d->err_size = err_size;
	int rc = tokenize(d, text);
	if (rc == 0)
		rc = decode_body(d);
	free(d);
	return rc;
}

double metar_cover_oktas(enum metar_cover c)
{
	switch (c) {
	case METAR_FEW: return 1.5;
	case METAR_SCT: return 3.5;
	case METAR_BKN: return 6.0;
	case METAR_OVC: return 8.0;
	default: return NAN;
	}
}

double metar_oktas(const struct metar *m)
{
	if (m->sky == METAR_SKY_OBSCURED)
		return 8.0;
	double oktas = m->sky == METAR_SKY_CLEAR ? 0.0 : NAN;
	for (int i = 0; i < m->n_clouds; i++) {
		double o = metar_cover_oktas(m->clouds[i].cover);
		if (!isnan(o) && (isnan(oktas) || o > oktas))
			oktas = o;
	}
	return oktas;
}

/* Where the layers' type changes with height: the middle and the high
 * clouds' bases in the mid latitudes (WMO International Cloud Atlas:
 * 2 and 6 km); stratus below 1000 ft where it is broken or overcast. */
#define METAR_MIDDLE_M 2000.0
#define METAR_HIGH_M 6000.0
#define METAR_STRATUS_M 300.0
#define FT_TO_M 0.3048
#define KT_TO_MPS (1852.0 / 3600.0)

/* v rounded to a step of 1 / per_unit (10, 100): the nearest double to a
 * short decimal, whose text (%.9g) reads back as the same double. */
static double round_to(double v, double per_unit)
{
	return round(v * per_unit) / per_unit;
}

static int layer_type(enum metar_cover cover, double base_m, const char *type)
{
	if (strcmp(type, "CB") == 0)
		return SKYCLOUD_CUMULONIMBUS;
	if (strcmp(type, "TCU") == 0)
		return SKYCLOUD_CUMULUS;
	if (base_m >= METAR_HIGH_M)
		return SKYCLOUD_CIRRUS;
	if (base_m >= METAR_MIDDLE_M)
		return SKYCLOUD_ALTOSTRATUS;
	if (cover >= METAR_BKN)
		return base_m < METAR_STRATUS_M ? SKYCLOUD_STRATUS : SKYCLOUD_STRATOCUMULUS;
	return SKYCLOUD_CUMULUS;
}

int metar_layers(const struct metar *m, struct metar_layer *ret, int max)
{
	int n = 0;

	if (m->sky == METAR_SKY_OBSCURED && isfinite(m->vertical_visibility_ft) && n < max)
		ret[n++] = (struct metar_layer){
			.oktas = 8.0, .type = SKYCLOUD_STRATUS,
			.base_m = round_to(m->vertical_visibility_ft * FT_TO_M, 10.0),
		};
	for (int i = 0; i < m->n_clouds && n < max; i++) {
		const struct metar_cloud *c = &m->clouds[i];
		if (c->cover == METAR_COVER_MISSING || !isfinite(c->height_ft))
			continue;
		double base_m = round_to(c->height_ft * FT_TO_M, 10.0);
		ret[n++] = (struct metar_layer){ .oktas = metar_cover_oktas(c->cover), .base_m = base_m,
						 .type = layer_type(c->cover, base_m, c->type) };
	}
	return n;
}

int metar_wind(const struct metar *m, double *ret_dir_deg, double *ret_speed_mps)
{
	double per;

	if (!isfinite(m->wind_speed))
		return -ENODATA;
	if (strcmp(m->wind_unit, "KT") == 0)
		per = KT_TO_MPS;
	else if (strcmp(m->wind_unit, "KMH") == 0)
		per = 1.0 / 3.6;
	else
		per = 1.0;
	*ret_dir_deg = m->wind_variable || !isfinite(m->wind_dir_deg) ? NAN
		       : fmod(m->wind_dir_deg, 360.0);
	*ret_speed_mps = round_to(m->wind_speed * per, 100.0);
	return 0;
}

/* Phenomena at the station (vicinity groups left out). */
static unsigned phenomena_here(const struct metar *m)
{
	unsigned p = 0;
	for (int i = 0; i < m->n_weather; i++)
		if (!m->weather[i].vicinity)
			p |= m->weather[i].phenomena;
	return p;
}

void metar_weather(const struct metar *m, struct weather *w)
{
	unsigned p = phenomena_here(m);

	w->visibility_km = NAN;
	if (!isnan(m->visibility_m) && m->visibility_qualifier != METAR_OR_MORE)
		w->visibility_km = fmin(fmax(m->visibility_m / 1000.0, WEATHER_VISIBILITY_MIN_KM),
					WEATHER_VISIBILITY_MAX_KM);
	double rh = weather_relative_humidity(m->temperature_c, m->dewpoint_c);
	w->relative_humidity = isnan(rh) ? NAN : fmin(fmax(rh, 0.0), 1.0);

	/* The obscuration that dominates the extinction picks the type. */
	w->aerosol = WEATHER_AEROSOL_AUTO;
	if (p & METAR_FG)
		w->aerosol = WEATHER_MARITIME;
	else if (p & (METAR_DU | METAR_SA | METAR_DS | METAR_SS | METAR_PO | METAR_VA))
		w->aerosol = WEATHER_DESERT;
	else if (p & METAR_FU)
		w->aerosol = WEATHER_URBAN;
	else if (p & (METAR_BR | METAR_PY))
		w->aerosol = WEATHER_MARITIME;
	else if (p & METAR_HZ)
		w->aerosol = WEATHER_CONTINENTAL;

	/* Without temperature and dew point, fog and mist say how damp the air
	 * is, and so does precipitation. */
	if (isnan(w->relative_humidity)) {
		if (p & METAR_FG)
			w->relative_humidity = 1.0;
		else if (p & (METAR_BR | METAR_PRECIPITATION))
			w->relative_humidity = 0.95;
	}
	w->cloud_oktas = metar_oktas(m);
	if (isnan(w->cloud_oktas) && (p & METAR_PRECIPITATION))
		w->cloud_oktas = 8.0;
}

static void emitf(weather_emit_fn fn, void *ctx, const char *key, const char *fmt, ...)
	__attribute__((format(printf, 4, 5)));
static void emitf(weather_emit_fn fn, void *ctx, const char *key, const char *fmt, ...)
{
	char buf[METAR_MAX_LEN];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(buf, sizeof(buf), fmt, ap);
	va_end(ap);
	fn(ctx, key, buf);
}

/* A number of struct metar under its field's name; missing when NAN. */
#define EMIT_FIELD(fn, ctx, m, field) emit_number(fn, ctx, #field, (m)->field)

static void emit_number(weather_emit_fn fn, void *ctx, const char *key, double v)
{
	if (isnan(v))
		fn(ctx, key, "missing");
	else
		emitf(fn, ctx, key, "%.9g", v);
}

static void describe_sky(const struct metar *m, weather_emit_fn fn, void *ctx)
{
	static const char *const covers[] = { "///", "FEW", "SCT", "BKN", "OVC" };
	static const char *const skies[] = { "none", "clear", "obscured" };
	char list[METAR_MAX_LEN] = "";

	for (int i = 0; i < m->n_clouds; i++) {
		const struct metar_cloud *c = &m->clouds[i];
		char one[32];
		if (isnan(c->height_ft))
			snprintf(one, sizeof(one), "%s///%s", covers[c->cover], c->type);
		else
			snprintf(one, sizeof(one), "%s%03d%s", covers[c->cover],
				 (int)lround(c->height_ft / 100.0), c->type);
		append(list, one);
	}
	fn(ctx, "sky", skies[m->sky]);
	fn(ctx, "clouds", list[0] ? list : "none");
	EMIT_FIELD(fn, ctx, m, vertical_visibility_ft);
}

void metar_describe(const struct metar *m, weather_emit_fn fn, void *ctx)
{
	static const char *const quals[] = { "exact", "or_more", "less_than" };
	char list[METAR_MAX_LEN] = "";

	fn(ctx, "type", m->type);
	fn(ctx, "station", m->station);
	emitf(fn, ctx, "time", "%02d%02d%02dZ", m->day, m->hour, m->minute);
	emitf(fn, ctx, "nil", "%d", m->nil);
	emitf(fn, ctx, "auto", "%d", m->automatic);
	emitf(fn, ctx, "cor", "%d", m->corrected);
	if (m->wind_variable)
		fn(ctx, "wind_dir_deg", "VRB");
	else
		EMIT_FIELD(fn, ctx, m, wind_dir_deg);
	EMIT_FIELD(fn, ctx, m, wind_speed);
	EMIT_FIELD(fn, ctx, m, wind_gust);
	fn(ctx, "wind_unit", m->wind_unit[0] ? m->wind_unit : "none");
	if (m->wind_from_deg >= 0)
		emitf(fn, ctx, "wind_sector_deg", "%d-%d", m->wind_from_deg, m->wind_to_deg);
	else
		fn(ctx, "wind_sector_deg", "none");
	emitf(fn, ctx, "cavok", "%d", m->cavok);
	EMIT_FIELD(fn, ctx, m, visibility_m);
	fn(ctx, "visibility_qualifier", quals[m->visibility_qualifier]);
	EMIT_FIELD(fn, ctx, m, min_visibility_m);
	fn(ctx, "min_visibility_dir", m->min_visibility_dir[0] ? m->min_visibility_dir : "none");
	emitf(fn, ctx, "rvr_groups", "%d", m->n_rvr);
	for (int i = 0; i < m->n_weather; i++)
		append(list, m->weather[i].code);
	fn(ctx, "weather", list[0] ? list : m->no_significant_weather ? "NSW" : "none");
	emitf(fn, ctx, "recent_groups", "%d", m->n_recent);
	describe_sky(m, fn, ctx);
	EMIT_FIELD(fn, ctx, m, temperature_c);
	EMIT_FIELD(fn, ctx, m, dewpoint_c);
	EMIT_FIELD(fn, ctx, m, qnh_hpa);
	emitf(fn, ctx, "wind_shear", "%d", m->wind_shear);
	fn(ctx, "trend", m->trend[0] ? m->trend : "none");
	emitf(fn, ctx, "remarks", "%d", m->remarks);
	fn(ctx, "used", m->used[0] ? m->used : "none");
	fn(ctx, "ignored", m->ignored[0] ? m->ignored : "none");
}
