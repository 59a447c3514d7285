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

layout(constant_id = 20) const int SV_AZ_GROUP = 8;
layout(local_size_x = 8, local_size_y = 8) in;

void main()
{
	load_params();
	int x0 = int(gl_GlobalInvocationID.x) * SV_AZ_GROUP, gy = int(gl_GlobalInvocationID.y);
	if (x0 >= OUT_W || gy >= OUT_H)
		return;
	// Rows below the horizon end on the ground after a few steps, rows above
	// take all of them. lavapipe hands each thread a contiguous share of the
	// workgroups, so invocation rows interleave the table's rows from both
	// ends: every workgroup gets half of each, every thread the same work.
	int py = (gy & 1) == 0 ? gy >> 1 : OUT_H - 1 - (gy >> 1);

	float h0 = P.planet.w;
	// The row's direction from angles that keep their bits: the horizon's
	// angle from the nadir, beta = atan(Rb / rho), rather than acos of its
	// cosine, and the angle from the nadir for rays that point down. From
	// 1e6 km the planet spans 0.36 degree around the nadir, where acos(mu_h)
	// lost 5e-6 rad (5 km at the limb) and a zenith angle near pi 2e-7.
	float beta = atan(P.planet.x, safe_sqrt(rho2(max(h0, 0.0)))), th = PI - beta;
	float x = clamp(tex_to_unit((float(py) + 0.5) / float(OUT_H), OUT_H), 0.0, 1.0);
	bool sky = x < 0.5;
	float sin_z, cos_z;
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
	vec3 dir[SV_AZ_GROUP], radiance[SV_AZ_GROUP];
	Phases ph_sun[SV_AZ_GROUP], ph_moon[SV_AZ_GROUP];
	// The lights' cosine to the local vertical at a step is
	// up_h * dot(across, light.xy) + up_z * light.z, with across the column's
	// horizontal unit vector: the dots are per column, up_h and up_z per step.
	float sun_h[SV_AZ_GROUP], moon_h[SV_AZ_GROUP];
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

	vec3 tr = vec3(1.0);
	Entry en;
	if (ray_in_shell(h0, dir[0], en)) {
		float len = en.len;
		float n_f = ceil(mix(P.misc.y, float(STEPS), clamp(len / 100.0, 0.0, 1.0)));
		int n = max(int(n_f), 1);
		// Each light's height over the local horizon (cosine units) at the
		// ends of the steps: the visible part of the disk is averaged over
		// each step (disk_visible_mean), not sampled at its midpoint.
		float sun_x[SV_AZ_GROUP], moon_x[SV_AZ_GROUP];
		{
			float rr, hb = altitude_along(en.h, en.mu, 0.0, rr);
			float up_h = sin_z * en.t0 / rr, up_z = en.ez / rr, mu_h = horizon_cos(hb);
			for (int j = 0; j < SV_AZ_GROUP; j++) {
				sun_x[j] = up_h * sun_h[j] + up_z * P.sun_dir.z - mu_h;
				if (MOON_LIT)
					moon_x[j] = up_h * moon_h[j] + up_z * P.moon_dir.z - mu_h;
			}
		}
		float prev = 0.0;
		for (int i = 0; i < n; i++) {
			float a = float(i + 1) / float(n);
			float next = len * a * a;
			float dt = next - prev, t = 0.5 * (prev + next), rr, rb_;
			prev = next;
			float hs = altitude_along(en.h, en.mu, t, rr);
			// The local vertical: its horizontal part follows each column.
			float up_h = sin_z * (en.t0 + t) / rr, up_z = (en.ez + cos_z * t) / rr;
			float sun_z = up_z * P.sun_dir.z, moon_z = up_z * P.moon_dir.z;
			// ... and at the step's far end.
			float hb = altitude_along(en.h, en.mu, next, rb_);
			float bup_h = sin_z * (en.t0 + next) / rb_, bup_z = (en.ez + cos_z * next) / rb_;
			float mu_hb = horizon_cos(hb), bsun_z = bup_z * P.sun_dir.z, bmoon_z = bup_z * P.moon_dir.z;
			Scatter sc;
			Medium m = medium_parts(hs, sc);
			TAlt ta = t_alt(hs);
			float e_sun = P.planet.x / ta.r * P.sun_dir.w, e_moon = P.planet.x / ta.r * P.moon_dir.w;
			vec3 step_t, w = tr * step_weight(m.extinction, dt, step_t);
			for (int j = 0; j < SV_AZ_GROUP; j++) {
				float xb = bup_h * sun_h[j] + bsun_z - mu_hb;
				float vis = disk_visible_mean(sun_x[j], xb, e_sun);
				sun_x[j] = xb;
				vec3 s = light_source_lit(ta, up_h * sun_h[j] + sun_z, vis, P.sun_illum.rgb,
							  phased(sc, ph_sun[j]), m.scattering);
				if (MOON_LIT) {
					xb = bup_h * moon_h[j] + bmoon_z - mu_hb;
					vis = disk_visible_mean(moon_x[j], xb, e_moon);
					moon_x[j] = xb;
					s += light_source_lit(ta, up_h * moon_h[j] + moon_z, vis, P.moon_illum.rgb,
							      phased(sc, ph_moon[j]), m.scattering);
				}
				radiance[j] += w * s;
			}
			tr *= step_t;
		}
	}
	float tr_mean = (tr.r + tr.g + tr.b) / 3.0;
	// Night-sky floor: L_z (1 + c (1 - mu)) over the sky, its airlight (1 - T) toward the ground.
	vec3 night = P.night.rgb * (1.0 + P.night.w * (1.0 - max(cos_z, 0.0))) *
		     (sky ? vec3(1.0) : 1.0 - tr);
	for (int j = 0; j < SV_AZ_GROUP; j++)
		if (x0 + j < OUT_W)
			STORE_TEXEL(SB, py * OUT_W + x0 + j, vec4(radiance[j] + night, tr_mean));
}
