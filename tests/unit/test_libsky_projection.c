/* test_libsky_projection.c - libsky's three projections (equirectangular,
 * perspective, fisheye) over the stand-in's tables (testkit/fake_skyd.h):
 * known directions at known pixels, round trips, the sun's disk where the
 * sun is, and a pixel off the disk equal to the sky-view sample. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "fake_skyd.h"
#include "sky.h"
#include "skysample.h"
#include "test.h"

#define PI SKYMAP_PI
#define DEG (PI / 180.0)

static struct fake_skyd fake;

static void test_projections(sky_client *c)
{
	struct sky_view v;
	CHECK_EQ(sky_view_begin(c, &v), 0);
	double sun_el = 30.0, sun_az = 120.0, dir[3], x, y;
	struct sky_render_params ps[3] = {
		{ .projection = SKY_PROJECTION_EQUIRECT, .width = 360, .height = 180 },
		{ .projection = SKY_PROJECTION_PERSPECTIVE, .width = 160, .height = 90, .yaw_deg = 100,
		  .pitch_deg = 20, .vfov_deg = 60 },
		{ .projection = SKY_PROJECTION_FISHEYE, .width = 201, .height = 151, .yaw_deg = 0 },
	};
	/* known directions to known pixels */
	skysample_direction(0.0, 90.0 * DEG, dir);
	CHECK(sky_render_position(&ps[0], dir, &x, &y) == 1 && fabs(x - 90) < 1e-9 && fabs(y - 90) < 1e-9);
	skysample_direction(90.0 * DEG, 0.0, dir);
	CHECK(sky_render_position(&ps[2], dir, &x, &y) == 1 && fabs(x - 100.5) < 1e-9 && fabs(y - 75.5) < 1e-9);
	skysample_direction(0.0, 0.0, dir);	/* north horizon: the bottom of the circle */
	CHECK(sky_render_position(&ps[2], dir, &x, &y) == 1 && fabs(x - 100.5) < 1e-9 &&
	      fabs(y - 151.0) < 1e-9);
	skysample_direction(0.0, 90.0 * DEG, dir);	/* east: the right */
	CHECK(sky_render_position(&ps[2], dir, &x, &y) == 1 && fabs(x - 176.0) < 1e-9 &&
	      fabs(y - 75.5) < 1e-9);
	skysample_direction(-5.0 * DEG, 0.0, dir);
	CHECK_EQ(sky_render_position(&ps[2], dir, &x, &y), 0);
	skysample_direction(20.0 * DEG, 100.0 * DEG, dir);	/* perspective axis: the centre */
	CHECK(sky_render_position(&ps[1], dir, &x, &y) == 1 && fabs(x - 80) < 1e-9 && fabs(y - 45) < 1e-9);
	CHECK_EQ(sky_render_direction(&ps[2], 0.5, 0.5, dir), 0);	/* corner outside */

	for (int n = 0; n < 3; n++) {
		struct sky_render_params p = ps[n];
		/* round trip at every 7th pixel */
		for (uint32_t py = 0; py < p.height; py += 7)
			for (uint32_t px = 0; px < p.width; px += 7) {
				double d[3], bx, by;
				if (sky_render_direction(&p, px + 0.5, py + 0.5, d) != 1)
					continue;
				if (sky_render_position(&p, d, &bx, &by) != 1 ||
				    fabs(bx - (px + 0.5)) > 1e-6 || fabs(by - (py + 0.5)) > 1e-6) {
					FAIL("projection %d: pixel (%u, %u) round trip (%g, %g)", n, px, py, bx, by);
					goto next;
				}
			}
	next:;
		/* the brightest pixel of a render is where the sun's disk is */
		p.flags = SKY_SAMPLE_SUN_DISK;
		float *img = malloc(sizeof(float) * 3 * p.width * p.height);
		CHECK_EQ(sky_render(&v, &p, img), 0);
		double best = -1, bx = 0, by = 0, sx, sy;
		double sum_x = 0, sum_y = 0, cnt = 0;
		for (uint32_t py = 0; py < p.height; py++)
			for (uint32_t px = 0; px < p.width; px++) {
				double val = img[(py * p.width + px) * 3];
				if (val > best) {
					best = val;
					bx = px + 0.5;
					by = py + 0.5;
				}
				if (val > 1000.0) {
					sum_x += px + 0.5;
					sum_y += py + 0.5;
					cnt++;
				}
			}
		skysample_direction(sun_el * DEG, sun_az * DEG, dir);
		CHECK_EQ(sky_render_position(&p, dir, &sx, &sy), 1);
		printf("projection %d: sun disk centroid (%.2f, %.2f) over %.0f px, expected (%.2f, %.2f)\n",
		       n, sum_x / cnt, sum_y / cnt, cnt, sx, sy);
		CHECK(cnt > 3 && fabs(sum_x / cnt - sx) < 1.0 && fabs(sum_y / cnt - sy) < 1.0);
		(void)bx, (void)by;
		/* a pixel off the disk holds the sky-view value in that direction */
		double d[3], rgb[3];
		double qx = p.width / 4 + 0.5, qy = p.height / 2 + 0.5;
		CHECK_EQ(sky_render_direction(&p, qx, qy, d), 1);
		double el = asin(d[2]) / DEG, az = atan2(d[0], d[1]) / DEG;
		CHECK_EQ(sky_sample_sky(&v, el, az, 0, rgb), 0);
		CHECK(fabsf(img[((p.height / 2) * p.width + p.width / 4) * 3 + 2] - (float)rgb[2]) <= 1e-6f * (float)rgb[2] + 1e-6f);
		free(img);
	}
	CHECK(sky_view_end(c, &v));
}

int main(void)
{
	fake_skyd_start(&fake);
	sky_client *c = fake_skyd_client(&fake);
	if (c) {
		test_projections(c);
		sky_disconnect(c);
	}
	fake_skyd_stop(&fake);
	return test_report("test_libsky_projection");
}
