/* pyprobe.c - libsky's side of the Python package's tests: the layout's
 * offsets as the C compiler lays them out, and libsky's CPU sampling of a
 * snapshot for queries read from stdin, printed with every digit.
 *
 *   pyprobe layout
 *   pyprobe SOCKET AT_LEAST < queries
 *
 * Queries, one a line (angles in degrees, lengths in km):
 *   sky EL AZ FLAGS           radiance (sky_sample_sky, FLAGS enum sky_sample_flags)
 *   trans ALT MU              sky_sample_transmittance
 *   sun | ambient             sky_sample_sun, sky_sample_ambient
 *   aerial U V D              sky_sample_aerial: rgb and T
 *   aerial_dir NAME X Y Z D   sky_sample_view_aerial_dir (NAME - : the state's camera)
 *   render PROJ W H YAW PITCH ROLL VFOV FLAGS
 *                             sky_render: W*H*3 floats, one pixel a line
 * The first line out is "generation G" of the snapshot all queries read.
 */
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sky.h"

#define OFF(type, field) printf("%s.%s %zu\n", #type, #field, offsetof(struct type, field))
#define SIZE(type) printf("%s %zu\n", #type, sizeof(struct type))

static void print_layout(void)
{
	SIZE(sky_shm_header);
	OFF(sky_shm_header, slot_bytes);
	OFF(sky_shm_header, generation);
	OFF(sky_shm_header, current_slot);
	OFF(sky_shm_header, superseded);
	OFF(sky_shm_header, tables);
	OFF(sky_shm_header, max_views);
	OFF(sky_shm_header, view_offset);
	OFF(sky_shm_header, view_stride);
	SIZE(sky_shm_table);
	OFF(sky_shm_table, offset);
	SIZE(sky_shm_slot);
	OFF(sky_shm_slot, generation);
	OFF(sky_shm_slot, apply_time_ns);
	OFF(sky_shm_slot, checksum);
	OFF(sky_shm_slot, state);
	OFF(sky_shm_slot, n_views);
	OFF(sky_shm_slot, valid_views);
	OFF(sky_shm_slot, views);
	OFF(sky_shm_slot, clouds);
	SIZE(sky_shm_state);
	OFF(sky_shm_state, ground_albedo);
	OFF(sky_shm_state, sun_direction);
	OFF(sky_shm_state, moon_angular_radius_rad);
	OFF(sky_shm_state, camera_up);
	OFF(sky_shm_state, aerial_squared);
	OFF(sky_shm_state, rgb_scale_log2);
	OFF(sky_shm_state, exposure_ev100);
	SIZE(sky_shm_view);
	OFF(sky_shm_view, altitude_km);
	OFF(sky_shm_view, camera_vfov_rad);
	OFF(sky_shm_view, form);
	OFF(sky_shm_view, panorama);
	SIZE(sky_shm_panorama);
	OFF(sky_shm_panorama, full_circle);
	OFF(sky_shm_panorama, azimuth0_rad);
	OFF(sky_shm_panorama, horizon_rad);
}

/* A snapshot of generation at_least or later holding every table. */
static int take(sky_client *c, unsigned at_least, void **ret_buf, struct sky_view *ret_view)
{
	size_t size = sky_snapshot_size(c);
	*ret_view = (struct sky_view){ 0 };
	void *buf = aligned_alloc(64, (size + 63) / 64 * 64);
	if (!buf)
		return -1;
	for (int tries = 0; tries < 1000; tries++) {
		if (sky_snapshot(c, buf, size, ret_view) == 0 && ret_view->slot->generation >= at_least &&
		    (ret_view->valid_tables & SKY_TABLES_ALL) == SKY_TABLES_ALL) {
			*ret_buf = buf;
			return 0;
		}
		if (sky_wait(c, ret_view->generation, 30000, NULL) < 0)
			break;
	}
	free(buf);
	return -1;
}

static void print3(const double v[3])
{
	printf("%.17g %.17g %.17g\n", v[0], v[1], v[2]);
}

static int render(const struct sky_view *v, const char *args)
{
	char proj[32];
	struct sky_render_params p = { 0 };
	if (sscanf(args, "%31s %u %u %lf %lf %lf %lf %u", proj, &p.width, &p.height, &p.yaw_deg,
		   &p.pitch_deg, &p.roll_deg, &p.vfov_deg, &p.flags) != 8)
		return -1;
	p.projection = !strcmp(proj, "fisheye") ? SKY_PROJECTION_FISHEYE :
		       !strcmp(proj, "perspective") ? SKY_PROJECTION_PERSPECTIVE : SKY_PROJECTION_EQUIRECT;
	float *rgb = malloc((size_t)p.width * p.height * 3 * sizeof(float));
	if (!rgb || sky_render(v, &p, rgb) < 0) {
		free(rgb);
		return -1;
	}
	for (size_t i = 0; i < (size_t)p.width * p.height; i++)
		printf("%.9g %.9g %.9g\n", rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]);
	free(rgb);
	return 0;
}

static int query(const struct sky_view *v, const char *line)
{
	double a, b, c, d, e, rgb[3], t;
	unsigned flags;
	char name[64];
	int r = -1;

	if (sscanf(line, "sky %lf %lf %u", &a, &b, &flags) == 3)
		r = sky_sample_sky(v, a, b, flags, rgb);
	else if (sscanf(line, "trans %lf %lf", &a, &b) == 2)
		r = sky_sample_transmittance(v, a, b, rgb);
	else if (!strncmp(line, "sun", 3))
		r = sky_sample_sun(v, rgb);
	else if (!strncmp(line, "ambient", 7))
		r = sky_sample_ambient(v, rgb);
	else if (sscanf(line, "aerial_dir %63s %lf %lf %lf %lf", name, &a, &b, &c, &d) == 5) {
		double dir[3] = { a, b, c };
		r = sky_sample_view_aerial_dir(v, strcmp(name, "-") ? name : NULL, dir, d, rgb, &t);
		if (r == 0)
			printf("%.17g %.17g %.17g %.17g\n", rgb[0], rgb[1], rgb[2], t);
		return r;
	} else if (sscanf(line, "aerial %lf %lf %lf", &a, &b, &e) == 3) {
		r = sky_sample_aerial(v, a, b, e, rgb, &t);
		if (r == 0)
			printf("%.17g %.17g %.17g %.17g\n", rgb[0], rgb[1], rgb[2], t);
		return r;
	} else if (!strncmp(line, "render ", 7))
		return render(v, line + 7);
	if (r == 0)
		print3(rgb);
	return r;
}

int main(int argc, char **argv)
{
	char line[512];
	sky_client *c;
	struct sky_view v;
	void *buf;

	if (argc == 2 && !strcmp(argv[1], "layout")) {
		print_layout();
		return 0;
	}
	if (argc != 3) {
		fprintf(stderr, "usage: pyprobe layout | pyprobe SOCKET AT_LEAST < queries\n");
		return 2;
	}
	if (sky_connect(argv[1], &c) < 0 || sky_subscribe(c, SKY_TABLES_ALL, 0) != 0) {
		fprintf(stderr, "pyprobe: cannot subscribe at %s\n", argv[1]);
		return 1;
	}
	if (take(c, (unsigned)strtoul(argv[2], NULL, 10), &buf, &v) < 0) {
		fprintf(stderr, "pyprobe: no snapshot of generation %s\n", argv[2]);
		return 1;
	}
	printf("generation %llu\n", (unsigned long long)v.slot->generation);
	while (fgets(line, sizeof(line), stdin)) {
		if (query(&v, line) < 0) {
			fprintf(stderr, "pyprobe: query failed: %s", line);
			return 1;
		}
	}
	free(buf);
	sky_disconnect(c);
	return 0;
}
