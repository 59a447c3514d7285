// aerial.comp - aerial perspective for each camera (view) in one dispatch:
// per froxel column, one march through all slices; slice k holds the
// integral from the camera to the slice's far edge (see proto/skymap.h).
// Volume 0 is the state's camera, then the registered views, each volume
// after the other in the output.
//
// Views that differ only by yaw (a display wall's channels on one eye
// point) see the same elevation profile in a froxel column: their rays
// cross the same altitudes at the same distances. eng.c groups them; one
// invocation marches a column once for its group (medium, view
// transmittance) and only the lights (phase, direction, transmittance and
// multi-scattering lookups) are per view, as in skyview.comp. A group is
// one dispatch, gl_WorkGroupID.z its index (vkCmdDispatchBase), compiled
// for its size: lavapipe runs both sides of a branch, so a loop over fewer
// views than the arrays hold would still pay for all of them.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

// The views in the group, at most 8. Their state lives in variables of
// their own, spelled out by VIEW_EACH: with arrays indexed in loops, a
// group of 4 already cost 3 times a group of 2 on lavapipe (the arrays
// left the registers).
layout(constant_id = 21) const int AP_GROUP = 1;
layout(local_size_x = 8, local_size_y = 8) in;

// v[0]: x the number of groups, y where the members start. Group g at
// 1 + 4 g: forward (w = tan(vfov / 2)), right (w = aspect), up (w = the
// altitude in km) of its camera at yaw 0, then (members, first member),
// members = AP_GROUP.
// Member m at y + m: (cos yaw, sin yaw, volume): the yaw turns the
// group's ray about the vertical.
layout(std430, binding = 7) readonly buffer ViewBuf { vec4 v[]; } VB;

// The aerial table again, a texel per element: lavapipe stores a vector in
// one loop over the lanes, where STORE_TEXEL's four words take four.
layout(std430, binding = 4) writeonly buffer AerialTexels { uvec4 d[]; } AT;
layout(std430, binding = 4) writeonly buffer AerialHalves { uvec2 d[]; } AH;

void store_texel(int i, vec4 v)
{
	if (STORAGE_F16)
		AH.d[i] = uvec2(packHalf2x16(v.xy), packHalf2x16(v.zw));
	else
		AT.d[i] = floatBitsToUint(v);
}

// A view's lights along the group's ray: the phase and the horizontal
// part of each light's cosine (dot(dir.xy, light.xy)) for its direction.
struct ViewLight {
	Phases sun, moon;
	float sun_h, moon_h;
	int volume;
};

ViewLight view_light(vec4 member, vec3 dir0)
{
	ViewLight v;
	vec3 dir = vec3(member.x * dir0.x + member.y * dir0.y, member.x * dir0.y - member.y * dir0.x,
			dir0.z);
	v.volume = int(member.z);
	v.sun = ray_phases(dir, P.sun_dir.xyz);
	v.sun_h = dot(dir.xy, P.sun_dir.xy);
	v.moon_h = 0.0;
	if (MOON_LIT) {
		v.moon = ray_phases(dir, P.moon_dir.xyz);
		v.moon_h = dot(dir.xy, P.moon_dir.xy);
	}
	return v;
}

// The in-scattered light of one step for a view: up_h, sun_z and moon_z
// are the step's, shared by the group.
vec3 view_source(ViewLight v, TAlt ta, Scatter sc, vec3 sigma_s, float up_h, float sun_z,
		 float moon_z)
{
	vec3 s = light_source(ta, up_h * v.sun_h + sun_z, P.sun_dir.w, P.sun_illum.rgb,
			      phased(sc, v.sun), sigma_s);
	if (MOON_LIT)
		s += light_source(ta, up_h * v.moon_h + moon_z, P.moon_dir.w, P.moon_illum.rgb,
				  phased(sc, v.moon), sigma_s);
	return s;
}

// Texels between volumes in device memory: AP_PAD_TEXELS in eng.c.
const int AP_PAD_TEXELS = 37;
const int VOLUME_TEXELS = OUT_D * OUT_H * OUT_W + AP_PAD_TEXELS;

#define VIEW_EACH(X) X(0) X(1) X(2) X(3) X(4) X(5) X(6) X(7)
#define VIEW_DECLARE(j) ViewLight vl##j; vec3 rad##j = vec3(0.0);
#define VIEW_INIT(j) if (AP_GROUP > j) vl##j = view_light(VB.v[first + j], dir0);
#define VIEW_STEP(j) if (AP_GROUP > j) \
	rad##j += w * view_source(vl##j, ta, sc, m.scattering, up_h, sun_z, moon_z);
#define VIEW_STORE(j) if (AP_GROUP > j) \
	store_texel(vl##j.volume * VOLUME_TEXELS + (k * OUT_H + px.y) * OUT_W + px.x, \
		    texel_rest + vec4(rad##j, 0.0));

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
	vec2 ndc = (vec2(px) + 0.5) / vec2(OUT_W, OUT_H) * 2.0 - 1.0;
	float range = P.cam_up.w;
	bool squared = P.misc.z > 0.5;
	// Night-sky floor: airlight (1 - T) of a sky of the floor's mean level L_z (1 + c / 3).
	vec3 night_level = P.night.rgb * (1.0 + P.night.w / 3.0);
	int g = int(gl_WorkGroupID.z), members_at = int(VB.v[0].y);
	vec4 fwd = VB.v[1 + 4 * g], right = VB.v[2 + 4 * g], cup = VB.v[3 + 4 * g];
	vec4 gm = VB.v[4 + 4 * g];
	int first = members_at + int(gm.y);
	float h0 = cup.w, tan_half = fwd.w;
	vec3 dir0 = normalize(fwd.xyz + ndc.x * tan_half * right.w * right.xyz +
			      ndc.y * tan_half * cup.xyz);

	// The lights' cosine to the local vertical at a step is
	// up_h * dot(dir.xy, light.xy) + up_z * light.z: the dots are per
	// view, up_h and up_z per step.
	VIEW_EACH(VIEW_DECLARE)
	VIEW_EACH(VIEW_INIT)

	Entry en;
	bool inside = ray_in_shell(h0, dir0, en);
	float t0 = en.t0, t1 = en.t0 + en.len;
	vec3 tr = vec3(1.0);
	float prev_depth = 0.0;
	for (int k = 0; k < OUT_D; k++) {
		float xk = float(k + 1) / float(OUT_D);
		float depth = range * (squared ? xk * xk : xk);
		// The part of this slice inside the atmosphere and above the ground.
		float a = max(prev_depth, t0), b = inside ? min(depth, t1) : a;
		prev_depth = depth;
		if (b > a) {
			float dt = (b - a) / float(STEPS);
			for (int i = 0; i < STEPS; i++) {
				float t = a + (float(i) + 0.5) * dt, rr;
				float hs = altitude_along(en.h, en.mu, t - t0, rr);
				float up_h = t / rr, up_z = (en.ez + dir0.z * (t - t0)) / rr;
				float sun_z = up_z * P.sun_dir.z, moon_z = up_z * P.moon_dir.z;
				Scatter sc;
				Medium m = medium_parts(hs, sc);
				TAlt ta = t_alt(hs);
				vec3 step_t, w = tr * step_weight(m.extinction, dt, step_t);
				VIEW_EACH(VIEW_STEP)
				tr *= step_t;
			}
		}
		vec4 texel_rest = vec4(night_level * (1.0 - tr), (tr.r + tr.g + tr.b) / 3.0);
		VIEW_EACH(VIEW_STORE)
	}
}
