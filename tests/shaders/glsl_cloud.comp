// glsl_cloud.comp - evaluates the functions of proto/glsl/skycloud.glsl for
// one input record per invocation, for test_glsl_cloud to check against
// proto/skycloud.h. The layers come as the C array of struct
// skycloud_layer, so that the two layouts are checked to be one.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "skycloud.glsl"

layout(local_size_x = 64) in;

// p: x, y, altitude h (km), layers of the group; q: the wind's offset,
// the planet's radius, the march's max_km; o: the ray's origin, its
// steps; d: its direction; h: a hash's input (i, j, k) and the group.
struct Record {
	vec4 p, q, o, d;
	uvec4 h;
};

layout(std430, binding = 0) readonly buffer Layers { SkycloudLayer l[]; } Ls;
layout(std430, binding = 1) readonly buffer In { Record r[]; } I;
layout(std430, binding = 2) writeonly buffer Out { vec4 v[]; } O;
layout(std430, binding = 3) writeonly buffer OutU { uvec4 v[]; } OU;

const int OUT_PER_RECORD = 3;

void main()
{
	int i = int(gl_GlobalInvocationID.x);
	if (i >= I.r.length())
		return;
	Record r = I.r[i];
	int g = int(r.h.w);
	SkycloudLayer group[SKYCLOUD_MAX_LAYERS];
	for (int k = 0; k < SKYCLOUD_MAX_LAYERS; k++)
		group[k] = Ls.l[4 * g + k];
	SkycloudLayer L = group[i & 3];
	int n = int(r.p.w);
	vec2 off = r.q.xy;
	float px = skycloud_wrap(r.p.x - off.x), py = skycloud_wrap(r.p.y - off.y);
	int o = OUT_PER_RECORD * i;
	O.v[o] = vec4(skycloud_coverage_fbm(L, px, py), skycloud_coverage_margin(L, r.p.x, r.p.y, off),
		      skycloud_coverage(L, r.p.x, r.p.y, off), skycloud_detail(L, px, py, skycloud_wrap(r.p.z)));
	O.v[o + 1] = vec4(skycloud_density(L, r.p.x, r.p.y, r.p.z, off),
			  skycloud_density_all(group, n, r.p.x, r.p.y, r.p.z, off),
			  skycloud_sky_occlusion(group, n, r.p.z),
			  skycloud_optical_depth(group, n, off, r.q.z, r.o.xyz, r.d.xyz, r.q.w, int(r.o.w)));
	O.v[o + 2] = vec4(skycloud_noise2(px, py, L.coverage_scale * 4.0, uvec3(r.h.xyz)),
			  skycloud_noise3(px, py, skycloud_wrap(r.p.z), L.detail_scale * 2.0, uvec3(r.h.zyx)),
			  skycloud_profile(L, fract(r.p.z)), float(SKYCLOUD_GLSL_VERSION));
	OU.v[i] = uvec4(skycloud_pcg3d(r.h.xyz), skycloud_hash3(r.h.x, r.h.y, r.h.z, uvec3(r.h.w, 7u, 9u)));
}
