// glsl_map.comp - evaluates every function of proto/glsl/skymap.glsl for one
// input record per invocation, for test_glsl_map to check against
// proto/skymap.h.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "skymap.glsl"

layout(local_size_x = 64) in;

// geo: rb, rt, altitude_km, mu; ang: horizon_cos, view zenith, azimuth,
// depth_km; tex: u, v, unit x, aerial range_km; n: width, height (also the
// slice count), slice k, aerial_squared; hor: the horizon's cos, sin and
// angle in double, rounded; dir: a view direction; pan: a panorama's
// azimuth0_rad, azimuth_step_rad, row0, row_step; pq: its horizon_rad and
// a direction's azimuth and elevation; pn: its width, height, full_circle.
struct Record {
	vec4 geo, ang, tex;
	ivec4 n;
	vec4 hor, dir, pan, pq;
	ivec4 pn;
};

layout(std430, binding = 0) readonly buffer In { Record r[]; } I;
layout(std430, binding = 1) writeonly buffer Out { vec4 v[]; } O;

const int OUT_PER_RECORD = 7;

void main()
{
	int i = int(gl_GlobalInvocationID.x);
	if (i >= I.r.length())
		return;
	Record r = I.r[i];
	float rb = r.geo.x, rt = r.geo.y, alt = r.geo.z, mu = r.geo.w;
	int w = r.n.x, h = r.n.y;
	bool squared = r.n.w != 0;
	int o = OUT_PER_RECORD * i;
	O.v[o] = vec4(skymap_transmittance_uv(rb, rt, alt, mu, w, h),
		      skymap_multiscatter_uv(rb, rt, alt, mu, w, h));
	O.v[o + 1] = vec4(skymap_transmittance_inverse(rb, rt, r.tex.xy, w, h),
			  skymap_multiscatter_inverse(rb, rt, r.tex.xy, w, h));
	O.v[o + 2] = vec4(skymap_skyview_uv(r.ang.x, r.ang.y, r.ang.z, h),
			  skymap_skyview_inverse(r.ang.x, r.tex.xy, h));
	O.v[o + 3] = vec4(skymap_aerial_depth_km(r.n.z, h, r.tex.w, squared),
			  skymap_aerial_slice(r.ang.w, h, r.tex.w, squared),
			  skymap_horizon_cos(rb, alt), skymap_distance_to_top(rb, rt, alt, mu));
	O.v[o + 4] = vec4(skymap_rho2(rb, alt), skymap_unit_to_tex(r.tex.z, w),
			  skymap_tex_to_unit(r.tex.x, w), 0.0);
	O.v[o + 5] = vec4(skymap_skyview_uv_dir(r.hor.x, r.hor.y, r.hor.z, r.dir.xyz, h),
			  float(SKYMAP_GLSL_VERSION), 0.0);
	O.v[o + 6] = vec4(skymap_panorama_uv(r.pan.x, r.pan.y, r.pan.z, r.pan.w, r.pq.x, r.pn.x,
					     r.pn.y, r.pn.z != 0, r.pq.y, r.pq.z), 0.0, 0.0);
}
