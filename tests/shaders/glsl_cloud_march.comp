// glsl_cloud_march.comp - runs proto/glsl/skycloud_march.glsl's march, its
// shadow on a point and its compositing for one record per invocation,
// for test_glsl_cloud_march to check against proto/skycloudmarch.h. The
// scene (layers, scattering, light) comes as the C arrays, so the layouts
// are checked with it.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "skycloud_march.glsl"

layout(local_size_x = 64) in;

// o: the ray's origin, its steps; d: its direction, max_km; m: light
// steps, jitter, 0, 0; g: a point for the shadow.
struct Record {
	vec4 o, d, m, g;
};

layout(std430, binding = 0) readonly buffer Scene {
	SkycloudLayer layers[SKYCLOUD_MAX_LAYERS];
	SkycloudScene sc;
	SkycloudLight li;
	SkyState sky;
} S;
layout(std430, binding = 1) readonly buffer In { Record r[]; } I;
layout(std430, binding = 2) writeonly buffer Out { vec4 v[]; } O;
layout(binding = 3) uniform sampler2D transmittance_tex;
layout(binding = 4) uniform sampler2D multiscatter_tex;
layout(binding = 5) uniform sampler2D coverage_tex;
layout(binding = 6) uniform sampler2D shadow_tex;

void main()
{
	int i = int(gl_GlobalInvocationID.x);
	if (i >= I.r.length())
		return;
	Record r = I.r[i];
	SkycloudSample c = skycloud_march(S.sky, transmittance_tex, multiscatter_tex, coverage_tex, shadow_tex,
					  S.layers, S.sc, S.li, r.o.xyz, r.d.xyz, r.d.w, int(r.o.w), int(r.m.x),
					  r.m.y);
	O.v[3 * i] = vec4(c.radiance, c.transmittance);
	O.v[3 * i + 1] = vec4(c.depth_km, skycloud_shadow_depth(shadow_tex, S.li.frame, r.g.xyz),
			      skycloud_shadow(shadow_tex, S.li.frame, r.g.xyz), 0.0);
	O.v[3 * i + 2] = vec4(skycloud_composite(vec3(1.0, 2.0, 3.0), c, vec4(0.25, 0.5, 0.75, 0.9)), 0.0);
}
