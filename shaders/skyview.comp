// skyview.comp - in-scattered sky radiance around the observer over the full
// circle of azimuth, non-linear latitude packed at the horizon, quadratic
// step spacing integrated to the very end of each ray, no sun disk.
//
// The rays of a row share their zenith angle, so they cross the same
// altitudes at the same distances: one invocation marches the medium once
// for SV_AZ_GROUP columns of a row, and only the lights (phase, direction,
// transmittance and multi-scattering lookups) are per column.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "clouds.glsl"

layout(constant_id = SPEC_SV_AZ_GROUP) const int SV_AZ_GROUP = 12;
layout(constant_id = SPEC_SV_EYE_UNDER) const bool SV_EYE_UNDER = false;
layout(constant_id = SPEC_SV_KEPT) const int SV_KEPT = SV_KEPT_OFF;
layout(local_size_x = 8, local_size_y = 8) in;

// The maps' light at each step of each column that reads them, sun and
// moon: the same maps, lights' frames and rays give the same light to the
// bit, so a change that keeps them all (the sun moving within its map's
// cell) reads it back rather than four texels and four exponentials
// (SPEC_SV_KEPT). By row, step, light and column of the invocation, then
// invocation along the row: neighbouring lanes touch neighbouring words.
layout(std430, binding = BINDING_SV_LIGHT) buffer SkyviewLight { float d[]; } SL;

// The local vertical (its horizontal part along the row's columns, up_h,
// and its vertical part, up_z) and the horizon's cosine at distance t along
// a row's rays: what a light's height over the horizon needs at the end of
// a march step.
struct StepEnd {
	float up_h, up_z, mu_h;
};

StepEnd step_end(Entry en, float sin_z, float cos_z, float t)
{
	float rr, h = altitude_along(en.h, en.mu, t, rr), inv = 1.0 / rr;
	StepEnd e;
	e.up_h = sin_z * (en.t0 + t) * inv;
	e.up_z = (en.ez + cos_z * t) * inv;
	e.mu_h = -safe_sqrt(rho2(max(h, 0.0))) * inv;	// horizon_cos(h): r = rb + h
	return e;
}

// A light's height over the horizon (mu_l - mu_horizon) in a column whose
// horizontal unit vector has dot light_h with the light's direction.
float over_horizon(StepEnd e, float light_h, float light_z)
{
	return e.up_h * light_h + e.up_z * light_z - e.mu_h;
}

// One invocation's row and columns, shared by the march's steps
// (march_step): the columns' directions, the lights' phases and
// horizontal dots, the radiance so far; the row's zenith angle, the ray's
// part in the shell, its steps, the transmittance along it (real and
// delta-M scaled), the peak's optical depth and the last step's end.
vec3 dir[SV_AZ_GROUP], radiance[SV_AZ_GROUP];
Phases ph_sun[SV_AZ_GROUP], ph_moon[SV_AZ_GROUP];
float sun_h[SV_AZ_GROUP], moon_h[SV_AZ_GROUP];
float sun_h_mean, moon_h_mean;	// over the columns: the layers' light (cloud_diffuse_at)
float h0, sin_z, cos_z, len, prev, tau_view;
int n;
int kept_row, kept_lane, kept_lanes;	// kept_light's: row, invocation, invocations a row
Entry en;
vec3 tr, tr_scaled;
StepEnd ea;

// Step i of the row's march from distance from_km on: its end, its
// middle, the middle's altitude and its local vertical (its horizontal
// part along the row's columns, up_h, and its vertical part, up_z). One
// function for march_step and march_range, so that both see the same
// middles to the bit.
struct StepMid {
	float next, t, hs, up_h, up_z;
};

StepMid step_mid(int i, float from_km)
{
	StepMid m;
	float a = float(i + 1) / float(n), rr;
	m.next = len * a * a;
	m.t = 0.5 * (from_km + m.next);
	m.hs = altitude_along(en.h, en.mu, m.t, rr);
	m.up_h = sin_z * (en.t0 + m.t) / rr;
	m.up_z = (en.ez + cos_z * m.t) / rr;
	return m;
}

// The light (0 sun, 1 moon) the maps let through at step i of the
// invocation's column j, at q: computed, kept as well, or read as kept
// (SV_KEPT).
float kept_light(int light, int j, int i, vec3 q)
{
	int at = (((kept_row * STEPS + i) * 2 + light) * SV_AZ_GROUP + j) * kept_lanes + kept_lane;
	if (SV_KEPT == SV_KEPT_READ)
		return SL.d[at];
	float lit = cloud_light(light, q);
	if (SV_KEPT == SV_KEPT_WRITE)
		SL.d[at] = lit;
	return lit;
}

// Step i of the row's march. shadowed: the step reads the shadow maps;
// march_range says which steps need to, and each loop that calls this
// with a constant compiles its own copy, without the reads or with them.
// A step that needs none is above the casters' ceiling, so above every
// layer's top: its copy leaves out the layers' light from above too.
void march_step(int i, const bool shadowed)
{
	StepMid mid = step_mid(i, prev);
	float next = mid.next, dt = next - prev, t = mid.t, hs = mid.hs;
	float up_h = mid.up_h, up_z = mid.up_z;
	prev = next;
	float sun_z = up_z * P.sun_dir.z, moon_z = up_z * P.moon_dir.z;
	StepEnd eb = step_end(en, sin_z, cos_z, next);
	Scatter sc;
	Medium m = medium_parts(hs, sc);
	// A step that does not read the maps is above every layer's top
	// (march_range): the sky above it is open, no layer sends light down.
	if (shadowed) {
		cloud_at(hs);
	} else {
		cloud_ms_open = 1.0;
		cloud_h_km = hs;
	}
	// The view's cos-zenith at the point is the same in every column.
	float view_up = sin_z * up_h + cos_z * up_z;
	vec3 ground = ground_scattering(sc, ground_excess(view_up)), forward = forward_scattering(sc);
	TAlt ta = t_alt(hs);
	float e_sun = P.BOTTOM_RADIUS_KM / ta.r * P.SUN_RADIUS_RAD, e_moon = P.BOTTOM_RADIUS_KM / ta.r * P.MOON_RADIUS_RAD;
	float sun_k = e_sun > 0.0 ? 0.5 / e_sun : 1e30, moon_k = e_moon > 0.0 ? 0.5 / e_moon : 1e30;
	vec3 step_t, w = tr * step_weight(m.extinction, dt, step_t);
	Scaled ds = scaled_step(sc, m, view_up, dt, tau_view);
	vec3 step_s = vec3(1.0), w_s = vec3(0.0);
	if (DELTA_CONST >= 0)
		w_s = tr_scaled * step_weight(m.extinction - ds.removed, dt, step_s);
	// The layers' light for the columns' mean light (clouds.glsl).
	vec3 sun_down = vec3(0.0), sun_up = vec3(0.0), moon_down = vec3(0.0), moon_up = vec3(0.0);
	if (CLOUD_LAYERS > 0) {
		cloud_diffuse_at(up_h * sun_h_mean + sun_z, !shadowed);
		sun_down = cloud_down;
		sun_up = cloud_up;
		if (MOON_LIT) {
			cloud_diffuse_at(up_h * moon_h_mean + moon_z, !shadowed);
			moon_down = cloud_down;
			moon_up = cloud_up;
		}
	}
	for (int j = 0; j < SV_AZ_GROUP; j++) {
		vec3 s = vec3(0.0), s_scaled = vec3(0.0);
		float vis = disk_visible_mean(over_horizon(ea, sun_h[j], P.sun_dir.z),
					      over_horizon(eb, sun_h[j], P.sun_dir.z), e_sun, sun_k);
		// The cloud's shadow at the step's middle (clouds.glsl).
		vec3 q = vec3(dir[j].xy * (en.t0 + t), h0 + dir[j].z * (en.t0 + t));
		if (SHADOW_W > 0 && shadowed)
			vis *= kept_light(0, j, i, q);
		cloud_down = sun_down;
		cloud_up = sun_up;
		march_source(ta, up_h * sun_h[j] + sun_z, vis, P.sun_illum.rgb, sc, ph_sun[j], m, ground,
			     forward, ds, view_up, s, s_scaled);
		if (MOON_LIT) {
			vis = disk_visible_mean(over_horizon(ea, moon_h[j], P.moon_dir.z),
						over_horizon(eb, moon_h[j], P.moon_dir.z), e_moon, moon_k);
			if (SHADOW_W > 0 && shadowed)
				vis *= kept_light(1, j, i, q);
			cloud_down = moon_down;
			cloud_up = moon_up;
			march_source(ta, up_h * moon_h[j] + moon_z, vis, P.moon_illum.rgb, sc, ph_moon[j], m,
				     ground, forward, ds, view_up, s, s_scaled);
		}
		radiance[j] += w * s;
		if (DELTA_CONST >= 0)
			radiance[j] += w_s * s_scaled;
	}
	if (DELTA_CONST >= 0)
		tr_scaled *= step_s;
	ea = eb;
	tr *= step_t;
}

// The lowest maps' light's cosine to the local vertical over the row's
// columns at a point of the ray whose local vertical is (up_h along the
// column, up_z): each light's horizontal part may point anywhere in
// azimuth. The maps' lights, not the lights: what the maps are read for,
// and the same while a light moves within its map's cell, so that the
// steps that read them are too (kept_light).
float lowest_light(float up_h, float up_z)
{
	vec3 sun = cloud_frame[0].l.xyz, moon = cloud_frame[1].l.xyz;
	float lo = up_z * sun.z - abs(up_h) * length(sun.xy);
	if (MOON_LIT)
		lo = min(lo, up_z * moon.z - abs(up_h) * length(moon.xy));
	return lo;
}

// The steps [ret_lo, ret_hi) of the row's march that read the shadow
// maps: every step whose middle is below the casters' ceiling or sees a
// light near or below its local horizontal, where the light's ray may
// pass under the casters (clouds.glsl, cloud_ceiling_km). Elsewhere
// cloud_light is 1 exactly.
void march_range(out int ret_lo, out int ret_hi)
{
	ret_lo = n;
	ret_hi = 0;
	float p = 0.0;
	int i = 0;
	do {
		StepMid mid = step_mid(i, p);
		p = mid.next;
		if (!(mid.hs > cloud_ceiling_km) || !(lowest_light(mid.up_h, mid.up_z) > 0.01)) {
			ret_lo = min(ret_lo, i);
			ret_hi = i + 1;
		}
	} while (++i < n);
}

void main()
{
	load_params();
	load_clouds();
	int x0 = int(gl_GlobalInvocationID.x) * SV_AZ_GROUP, gy = int(gl_GlobalInvocationID.y);
	if (x0 >= OUT_W || gy >= OUT_H)
		return;
	// Rows below the horizon end on the ground after a few steps, rows above
	// take all of them: every workgroup gets half of each.
	int py = interleaved_row(gy, OUT_H);
	kept_row = py;
	kept_lane = int(gl_GlobalInvocationID.x);
	kept_lanes = int(gl_NumWorkGroups.x * gl_WorkGroupSize.x);

	h0 = P.OBSERVER_KM;
	// The row's direction from angles that keep their bits: the horizon's
	// angle from the nadir, beta = atan(Rb / rho), rather than acos of its
	// cosine, and the angle from the nadir for rays that point down. From
	// 1e6 km the planet spans 0.36 degree around the nadir, where acos(mu_h)
	// lost 5e-6 rad (5 km at the limb) and a zenith angle near pi 2e-7.
	float beta = atan(P.BOTTOM_RADIUS_KM, safe_sqrt(rho2(max(h0, 0.0)))), th = PI - beta;
	float x = clamp(tex_to_unit((float(py) + 0.5) / float(OUT_H), OUT_H), 0.0, 1.0);
	bool sky = x < 0.5;
	if (sky) {
		float a = 1.0 - 2.0 * x, zenith = th * (1.0 - a * a);
		if (zenith <= 0.5 * PI) {
			sin_z = sin(zenith);
			cos_z = cos(zenith);
		} else {
			float nadir = beta + th * a * a;
			sin_z = sin(nadir);
			cos_z = -cos(nadir);
		}
	} else {
		float a = 2.0 * x - 1.0, nadir = beta * (1.0 - a * a);
		sin_z = sin(nadir);
		cos_z = -cos(nadir);
	}
	// The lights' cosine to the local vertical at a step is
	// up_h * dot(across, light.xy) + up_z * light.z, with across the column's
	// horizontal unit vector: the dots are per column, up_h and up_z per step.
	for (int j = 0; j < SV_AZ_GROUP; j++) {
		float az = 2.0 * PI * (float(min(x0 + j, OUT_W - 1)) + 0.5) / float(OUT_W);
		vec2 across = vec2(sin(az), cos(az));
		dir[j] = vec3(sin_z * across, cos_z);
		ph_sun[j] = ray_phases(dir[j], P.sun_dir.xyz);
		sun_h[j] = dot(across, P.sun_dir.xy);
		if (MOON_LIT) {
			ph_moon[j] = ray_phases(dir[j], P.moon_dir.xyz);
			moon_h[j] = dot(across, P.moon_dir.xy);
		}
		radiance[j] = vec3(0.0);
	}
	sun_h_mean = moon_h_mean = 0.0;
	for (int j = 0; j < SV_AZ_GROUP; j++) {
		sun_h_mean += sun_h[j] / float(SV_AZ_GROUP);
		if (MOON_LIT)
			moon_h_mean += moon_h[j] / float(SV_AZ_GROUP);
	}

	tr = vec3(1.0);
	tr_scaled = vec3(1.0);	// through the delta-M scaled medium (delta_source)
	tau_view = 0.0;		// the peak's optical depth along it (scaled_step)
	if (ray_in_shell(h0, dir[0], en)) {
		len = en.len;
		float n_f = ceil(mix(P.SKYVIEW_MIN_STEPS, float(STEPS), clamp(len / 100.0, 0.0, 1.0)));
		n = max(int(n_f), 1);
		// The visible part of each light's disk is averaged over each step
		// (disk_visible_mean) from the light's height over the local horizon
		// at the step's two ends.
		ea = step_end(en, sin_z, cos_z, 0.0);
		prev = 0.0;
		// A row's columns share its steps' altitudes: the steps that read
		// the shadow maps are a range, the same for all of them. A for
		// loop costs lavapipe one step more than it runs (its last test
		// comes after a step with every lane off), so a clear sky keeps
		// one do-while, and the loops around the range are do-whiles
		// behind a test of the row's own count.
		int i = 0;
		if (SHADOW_W == 0) {
			do
				march_step(i++, false);
			while (i < n);
		} else {
			int lo, hi;
			march_range(lo, hi);
			// The middle loop runs at least once (a do-while): a row that
			// needs no map reads the maps at its last step, where they
			// read 1 exactly.
			if (hi <= lo) {
				lo = n - 1;
				hi = n;
			}
			// Under the casters' top nearly every row reads the maps from
			// its first step on: without the first loop, which would cost
			// lavapipe a step with every lane off. A step before lo that
			// reads them reads 1 exactly, and no layer is above it.
			if (!SV_EYE_UNDER && i < lo) {
				do
					march_step(i++, false);
				while (i < lo);
			}
			do
				march_step(i++, true);
			while (i < hi);
			if (i < n) {
				do
					march_step(i++, false);
				while (i < n);
			}
		}
	}
	float tr_mean = (tr.r + tr.g + tr.b) / 3.0;
	// Night-sky floor: L_z (1 + c (1 - mu)) over the sky, its airlight (1 - T) toward the ground.
	vec3 night = P.night.rgb * (1.0 + P.NIGHT_GAIN * (1.0 - max(cos_z, 0.0))) *
		     (sky ? vec3(1.0) : 1.0 - tr);
	for (int j = 0; j < SV_AZ_GROUP; j++)
		if (x0 + j < OUT_W) {
			STORE_TEXEL(SB, py * OUT_W + x0 + j, vec4(radiance[j] + night, tr_mean));
			note_range(radiance[j] + night);
		}
	flush_range(BINDING_SKYVIEW - BINDING_TRANSMITTANCE);
}
