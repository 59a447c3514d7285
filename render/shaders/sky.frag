#version 450
#extension GL_GOOGLE_include_directive : require
// sky.frag - the sky of one pixel: the sky-view table toward the pixel's
// direction and the sun and moon disks, through the GLSL library, and the
// clouds in front of them; linear radiance (cd/m2), the same as skyctl
// render's before its tone curve.
#include "frame.glsl"

layout(location = 0) out vec4 out_colour;

void main()
{
	vec3 dir;
	if (!view_direction(gl_FragCoord.xy + F.wall.zw, dir)) {
		out_colour = vec4(0.0, 0.0, 0.0, 1.0);
		return;
	}
	vec3 l = sky_radiance(F.sky[0], skyview_tex, dir) +
		 sky_disks(F.sky[0], transmittance_tex, dir, int(F.ambient_lx.w));
	out_colour = vec4(clouds_over(dir, 1e30, l), 1.0);
}
