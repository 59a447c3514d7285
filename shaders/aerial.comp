// aerial.comp - aerial perspective for each camera (view) in one dispatch:
// per froxel column, one march through all slices; slice k holds the
// integral from the camera to the slice's far edge (see proto/skymap.h).
// gl_GlobalInvocationID.z is the view: 0 the state's camera, then the
// registered views, each volume after the other in the output.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Per view, three vec4: forward (w = tan(vfov / 2)), right (w = aspect),
// up (w = the view's altitude in km).
layout(std430, binding = BINDING_VIEWS) readonly buffer ViewBuf { vec4 v[]; } VB;

// The aerial table again, a texel per element: lavapipe stores a vector
// with one loop over the lanes where STORE_TEXEL's four words take four,
// and a column stores OUT_D texels.
layout(std430, binding = BINDING_AERIAL) writeonly buffer AerialTexels { uvec4 d[]; } AT;

void store_texel(int i, vec4 v)
{
	AT.d[i] = floatBitsToUint(v);
	note_range(v.rgb);
}

void main()
{
	load_params();
	ivec2 px = ivec2(gl_GlobalInvocationID.xy);
	if (px.x >= OUT_W || px.y >= OUT_H)
		return;
	// Rows that look at the ground end early: interleave the volume's rows
	// from both ends so that lavapipe's contiguous shares of workgroups
	// carry the same work (as in skyview.comp).
	px.y = (px.y & 1) == 0 ? px.y >> 1 : OUT_H - 1 - (px.y >> 1);

	int view = int(gl_GlobalInvocationID.z);
	vec4 fwd = VB.v[3 * view], right = VB.v[3 * view + 1], cup = VB.v[3 * view + 2];
	float h0 = cup.w, range = P.cam_up.w;
	vec2 ndc = (vec2(px) + 0.5) / vec2(OUT_W, OUT_H) * 2.0 - 1.0;
	float tan_half = fwd.w;
	vec3 dir = normalize(fwd.xyz + ndc.x * tan_half * right.w * right.xyz +
			     ndc.y * tan_half * cup.xyz);

	Phases ph_sun = ray_phases(dir, P.sun_dir.xyz), ph_moon = ray_phases(dir, P.moon_dir.xyz);
	float sun_v = dot(dir, P.sun_dir.xyz), moon_v = dot(dir, P.moon_dir.xyz);
	Entry en;
	bool inside = ray_in_shell(h0, dir, en);
	float t0 = en.t0, t1 = en.t0 + en.len;
	vec3 radiance = vec3(0.0), tr = vec3(1.0);
	vec3 tr_scaled = vec3(1.0);	// through the delta-M scaled medium (delta_source)
	float tau_view = 0.0;		// the peak's optical depth along it (scaled_step)
	float prev_depth = 0.0;
	for (int k = 0; k < OUT_D; k++) {
		float depth = skymap_aerial_depth_km(k, OUT_D, range, P.misc.z > 0.5);
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
				float mu_l = dot(up, P.sun_dir.xyz);
				march_source(ta, mu_l, light_visible(ta, mu_l, P.sun_dir.w), P.sun_illum.rgb, sc, ph_sun, m,
					     ground, forward, ds, view_up, sun_v, s, s_scaled);
				if (MOON_LIT) {
					mu_l = dot(up, P.moon_dir.xyz);
					march_source(ta, mu_l, light_visible(ta, mu_l, P.moon_dir.w), P.moon_illum.rgb, sc,
						     ph_moon, m, ground, forward, ds, view_up, moon_v, s, s_scaled);
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
		// Night-sky floor: airlight (1 - T) of a sky of the floor's mean level L_z (1 + c / 3).
		vec3 night = P.night.rgb * (1.0 + P.night.w / 3.0) * (1.0 - tr);
		store_texel(((view * OUT_D + k) * OUT_H + px.y) * OUT_W + px.x,
			    vec4(radiance + night, (tr.r + tr.g + tr.b) / 3.0));
	}
	flush_range(BINDING_AERIAL - BINDING_TRANSMITTANCE);
}
