// cloud.comp - the coverage table: texel (i, j) of the square region of
// half-width FIELD_EXTENT_KM around the observer, east along i, north along
// j, holds in channel k the coverage of layer k + 1 (cloudN, N = k + 1:
// the layer's own index), skycloud_coverage at the texel's centre with the
// wind's offset; 0 where no layer k + 1 is drawn.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "clouds.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = BINDING_CLOUD) writeonly buffer CloudTexels { vec4 d[]; } CT;

void main()
{
	ivec2 px = ivec2(gl_GlobalInvocationID.xy);
	if (px.x >= CLOUD_W || px.y >= CLOUD_W)
		return;
	float e = CL.FIELD_EXTENT_KM, step_km = 2.0 * e / float(CLOUD_W);
	float x = -e + (float(px.x) + 0.5) * step_km, y = -e + (float(px.y) + 0.5) * step_km;
	vec2 offset = vec2(CL.FIELD_OFFSET_EAST_KM, CL.FIELD_OFFSET_NORTH_KM);
	vec4 v = vec4(0.0);
	for (int i = 0; i < CLOUD_LAYERS; i++)
		v[CL.layer[i].index & 3u] = skycloud_coverage(CL.layer[i], x, y, offset);
	CT.d[px.y * CLOUD_W + px.x] = v;
}
