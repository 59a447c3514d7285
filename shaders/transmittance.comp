// transmittance.comp - transmittance to the top of the atmosphere per
// (altitude, zenith cosine), Bruneton's mapping, from the column densities
// that columns.comp computed for the same texels and kept: a change of
// coefficients alone runs only this pass (a change of the columns runs
// columns.comp, which writes the table itself).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "transmittance.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main()
{
	load_params();
	ivec2 px = ivec2(gl_GlobalInvocationID.xy);
	if (px.x >= OUT_W || px.y >= OUT_H)
		return;
	int i = px.y * OUT_W + px.x;
	store_transmittance(i, CB.d[i]);
}
