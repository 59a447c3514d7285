// skyview.comp - in-scattered sky radiance around the observer over the full
// circle of azimuth, non-linear latitude packed at the horizon, quadratic
// step spacing integrated to the very end of each ray, no sun disk.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main()
{
	ivec2 px = ivec2(gl_GlobalInvocationID.xy);
	if (px.x >= OUT_W || px.y >= OUT_H)
		return;

	float h0 = P.planet.w;
	float th = acos(clamp(P.misc.x, -1.0, 1.0));
	float x = clamp(tex_to_unit((float(px.y) + 0.5) / float(OUT_H), OUT_H), 0.0, 1.0);
	float zenith;
	if (x < 0.5) {
		float a = 1.0 - 2.0 * x;
		zenith = th * (1.0 - a * a);
	} else {
		float a = 2.0 * x - 1.0;
		zenith = th + (PI - th) * a * a;
	}
	float az = 2.0 * PI * (float(px.x) + 0.5) / float(OUT_W);
	vec3 dir = vec3(sin(zenith) * sin(az), sin(zenith) * cos(az), cos(zenith));

	vec3 radiance = vec3(0.0), tau = vec3(0.0);
	Phases ph_sun = ray_phases(dir, P.sun_dir.xyz), ph_moon = ray_phases(dir, P.moon_dir.xyz);
	float t0, t1;
	if (ray_in_shell(h0, dir, t0, t1)) {
		float len = t1 - t0;
		float n_f = ceil(mix(P.misc.y, float(STEPS), clamp(len / 100.0, 0.0, 1.0)));
		int n = max(int(n_f), 1);
		float r0 = P.planet.x + h0;
		float prev = 0.0;
		for (int i = 0; i < n; i++) {
			float a = float(i + 1) / float(n);
			float next = len * a * a;
			float dt = next - prev, t = t0 + 0.5 * (prev + next), rr;
			prev = next;
			float hs = altitude_along(h0, dir.z, t, rr);
			vec3 up = vec3(dir.xy * t, r0 + dir.z * t) / rr;
			Step st = sample_step(hs, ph_sun, ph_moon);
			Medium m = st.m;
			vec3 s = light_source(hs, up, P.sun_dir.xyz, P.sun_illum.rgb, st.phased_sun, m.scattering);
			if (MOON_LIT)
				s += light_source(hs, up, P.moon_dir.xyz, P.moon_illum.rgb, st.phased_moon, m.scattering);
			radiance += exp(-tau) * s * segment_weight(m.extinction, dt);
			tau += m.extinction * dt;
		}
	}
	vec3 tr = exp(-tau);
	// Night-sky floor: L_z (1 + c (1 - mu)) over the sky, its airlight (1 - T) toward the ground.
	radiance += P.night.rgb * (1.0 + P.night.w * (1.0 - max(dir.z, 0.0))) * (dir.z > P.misc.x ? vec3(1.0) : 1.0 - tr);
	STORE_TEXEL(SB, px.y * OUT_W + px.x, vec4(radiance, (tr.r + tr.g + tr.b) / 3.0));
}
