// aerial.comp - aerial perspective, every march job in one dispatch: per
// froxel column, one march through all slices; slice k holds the integral
// from the eye to the slice's far edge (see proto/skymap.h).
// gl_GlobalInvocationID.z is the job (sky_params.h, struct AerialJob): a
// camera's volume (the state's camera, a view), or the panorama of an eye
// point that several cameras share, which views of form panorama read and
// aerial_resample.comp resamples into the volumes of the others.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "clouds.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// The jobs (eng_fill_views): a camera's frame, or a panorama's mapping
// (aplan.c); both with the eye's altitude, the sun and the moon in the
// eye's local frame and the output's first texel.
layout(std430, binding = BINDING_VIEWS) readonly buffer ViewBuf { uvec4 head; AerialJob job[]; } VB;

// The aerial table again, a texel per element: lavapipe stores a vector
// with one loop over the lanes where STORE_TEXEL's four words take four,
// and a column stores OUT_D texels.
layout(std430, binding = BINDING_AERIAL) writeonly buffer AerialTexels { uvec4 d[]; } AT;

void store_texel(int i, vec4 v)
{
	AT.d[i] = floatBitsToUint(v);
	note_range(v.rgb);
}

// The direction of column i, row j of job z's panorama; around the full
// circle the last column is the first again, bit for bit.
vec3 panorama_dir(uint z, int i, int j)
{
	if (VB.job[z].full_circle > 0.5)
		i %= int(VB.job[z].width) - 1;
	float az = VB.job[z].azimuth0_rad + float(i) * VB.job[z].azimuth_step_rad;
	float x = VB.job[z].row0 + float(j) * VB.job[z].row_step;
	float el = VB.job[z].horizon_rad + sign(x) * x * x;
	return vec3(cos(el) * sin(az), cos(el) * cos(az), sin(el));
}

// Slice k's texel from the march so far: the radiance and the view's
// transmittance to the slice's far edge, and the night sky's floor,
// airlight (1 - T) of a sky of the floor's mean level L_z (1 + c / 3).
vec4 slice_texel(vec3 radiance, vec3 tr)
{
	vec3 night = P.night.rgb * (1.0 + P.NIGHT_GAIN / 3.0) * (1.0 - tr);
	return vec4(radiance + night, (tr.r + tr.g + tr.b) / 3.0);
}

// A panorama is published in float32 (views of form panorama) or
// resampled into volumes, whose range is noted there. Its radiance is kept
// as a logarithm, which readers interpolate: below the horizon the
// airlight goes as the distance to the ground, about 1 / sin of the
// depression, which is far closer to linear in log than in radiance.
void store_slice(bool panorama, int out_base, int k, int pano_texels, int col, ivec2 px, vec4 texel)
{
	if (panorama)
		AT.d[out_base + k * pano_texels + col] = floatBitsToUint(vec4(log(max(texel.rgb, vec3(1e-30))), texel.a));
	else
		store_texel(out_base + (k * OUT_H + px.y) * OUT_W + px.x, texel);
}

void main()
{
	load_params();
	load_clouds();
	ivec2 px = ivec2(gl_GlobalInvocationID.xy);
	uint z = gl_GlobalInvocationID.z;
	vec3 sun_dir = VB.job[z].sun, moon_dir = VB.job[z].moon;
	int out_base = int(VB.job[z].out_texel);
	bool panorama = VB.job[z].kind == AERIAL_JOB_PANORAMA;
	float pano_w = VB.job[z].width, pano_h = VB.job[z].height;
	// A panorama's columns, row-major, take rows of OUT_W invocations,
	// as many as they need (the dispatch has enough for the largest).
	int pw = int(pano_w), rows = panorama ? (pw * int(pano_h) + OUT_W - 1) / OUT_W : OUT_H;
	if (px.x >= OUT_W || px.y >= rows)
		return;
	// Rows that look at the ground end early (interleaved_row()).
	px.y = interleaved_row(px.y, rows);

	float h0 = VB.job[z].eye_km, range = P.AERIAL_RANGE_KM;
	vec3 dir;
	int col = px.y * OUT_W + px.x;		// the panorama's column
	if (panorama) {
		if (col >= pw * int(pano_h))
			return;
		dir = panorama_dir(z, col % pw, col / pw);
	} else {
		vec2 ndc = (vec2(px) + 0.5) / vec2(OUT_W, OUT_H) * 2.0 - 1.0;
		float tan_half = VB.job[z].tan_half_vfov;
		dir = normalize(VB.job[z].fwd + ndc.x * tan_half * VB.job[z].aspect * VB.job[z].right +
				ndc.y * tan_half * VB.job[z].up);
	}

	Phases ph_sun = ray_phases(dir, sun_dir), ph_moon = ray_phases(dir, moon_dir);
	// The job's eye frame in the observer's, where the shadow maps are
	// read (clouds.glsl): a view elsewhere marches from its own ground
	// point, under its own part of the field.
	mat3 eye_site = mat3(VB.job[z].site_east, VB.job[z].site_north, VB.job[z].site_up);
	vec3 eye_ground = vec3(VB.job[z].ground_east_km, VB.job[z].ground_north_km, VB.job[z].ground_up_km);
	Entry en;
	bool inside = ray_in_shell(h0, dir, en);
	float t0 = en.t0, t1 = en.t0 + en.len;
	vec3 radiance = vec3(0.0), tr = vec3(1.0);
	vec3 tr_scaled = vec3(1.0);	// through the delta-M scaled medium (delta_source)
	float tau_view = 0.0;		// the peak's optical depth along it (scaled_step)
	float prev_depth = 0.0;
	int k = 0;
	for (; k < OUT_D; k++) {
		// Past the ray's end (the ground, the top, or a ray that misses)
		// no slice marches: lavapipe would still run the march for these
		// lanes, masked, until every lane of the row had ended.
		if (!inside || prev_depth >= t1)
			break;
		float depth = skymap_aerial_depth_km(k, OUT_D, range, P.AERIAL_SQUARED > 0.5);
		// The part of this slice inside the atmosphere and above the ground.
		float a = max(prev_depth, t0), b = inside ? min(depth, t1) : a;
		prev_depth = depth;
		if (b > a) {
			float dt = (b - a) / float(STEPS);
			for (int i = 0; i < STEPS; i++) {
				float t = a + (float(i) + 0.5) * dt, rr;
				float hs = altitude_along(en.h, en.mu, t - t0, rr);
				vec3 up = vec3(dir.xy * t, en.ez + dir.z * (t - t0)) / rr;
				float view_up = dot(up, dir);
				TAlt ta = t_alt(hs);
				Scatter sc;
				Medium m = medium_parts(hs, sc);
				vec3 ground = ground_scattering(sc, ground_excess(view_up)), forward = forward_scattering(sc);
				Scaled ds = scaled_step(sc, m, view_up, dt, tau_view);
				vec3 s = vec3(0.0), s_scaled = vec3(0.0);
				float mu_l = dot(up, sun_dir);
				float vis = light_visible(ta, mu_l, P.SUN_RADIUS_RAD);
				// The clouds (clouds.glsl): the point in the observer's frame.
				vec3 q = eye_ground + eye_site * vec3(dir.xy * t, h0 + dir.z * t);
				if (SHADOW_W > 0)
					vis *= cloud_step(q, hs);
				if (CLOUD_LAYERS > 0)
					cloud_diffuse_at(mu_l, false);
				march_source(ta, mu_l, vis, P.sun_illum.rgb, sc, ph_sun, m, ground, forward, ds, view_up,
					     s, s_scaled);
				if (MOON_LIT) {
					mu_l = dot(up, moon_dir);
					vis = light_visible(ta, mu_l, P.MOON_RADIUS_RAD) *
					      (SHADOW_W > 0 ? cloud_light(1, q) : 1.0);
					if (CLOUD_LAYERS > 0)
						cloud_diffuse_at(mu_l, false);
					march_source(ta, mu_l, vis, P.moon_illum.rgb, sc, ph_moon, m, ground, forward, ds,
						     view_up, s, s_scaled);
				}
				vec3 step_t;
				radiance += tr * s * step_weight(m.extinction, dt, step_t);
				if (DELTA_CONST >= 0) {
					vec3 step_s;
					radiance += tr_scaled * s_scaled * step_weight(m.extinction - ds.removed, dt, step_s);
					tr_scaled *= step_s;
				}
				tr *= step_t;
			}
		}
		store_slice(panorama, out_base, k, int(pano_w * pano_h), col, px, slice_texel(radiance, tr));
	}
	// The slices beyond hold what the march reached.
	vec4 last = slice_texel(radiance, tr);
	for (; k < OUT_D; k++)
		store_slice(panorama, out_base, k, int(pano_w * pano_h), col, px, last);
	flush_range(BINDING_AERIAL - BINDING_TRANSMITTANCE);
}
