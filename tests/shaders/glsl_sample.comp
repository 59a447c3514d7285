// glsl_sample.comp - a render client's use of proto/glsl/sky.glsl: per query,
// the sky toward a direction, the disks, the transmittance toward it and at
// an (altitude, mu), aerial perspective at a screen position and distance,
// the multi-scattering table, the sun's and the moon's illuminance, where
// the direction falls in the aerial volume's camera, and aerial perspective
// toward the direction (a volume or a view's panorama); for
// test_glsl_sample to check against libsky's CPU sampling. Built twice: with
// the texture units' filtering and with SKY_GLSL_EXACT_FILTER.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "sky.glsl"

layout(local_size_x = 64) in;

layout(std140, binding = 0) uniform SkyBlock { SkyState sky; };
layout(binding = 1) uniform sampler2D transmittance_tex;
layout(binding = 2) uniform sampler2D multiscatter_tex;
layout(binding = 3) uniform sampler2D skyview_tex;	// REPEAT in u
layout(binding = 4) uniform sampler3D aerial_tex;

// dir: a view direction (unit, ENU), w a distance in km; p: a screen
// position (xy), an altitude in km and a cos-zenith.
struct Query {
	vec4 dir, p;
};
layout(std430, binding = 5) readonly buffer Queries { Query q[]; } Q;
layout(std430, binding = 6) writeonly buffer Results { vec4 r[]; } R;

const int RESULTS_PER_QUERY = 9;

void main()
{
	int i = int(gl_GlobalInvocationID.x);
	if (i >= Q.q.length())
		return;
	vec3 dir = Q.q[i].dir.xyz;
	vec4 p = Q.q[i].p;
	int o = RESULTS_PER_QUERY * i;
	R.r[o] = vec4(sky_radiance(sky, skyview_tex, dir), 0.0);
	R.r[o + 1] = vec4(sky_disks(sky, transmittance_tex, dir,
				    SKY_DISK_SUN | SKY_DISK_MOON | SKY_DISK_LIMB_DARKENING), 0.0);
	R.r[o + 2] = vec4(sky_light_transmittance(sky, transmittance_tex, dir), 0.0);
	R.r[o + 3] = vec4(sky_transmittance(sky, transmittance_tex, p.z, p.w), 0.0);
	R.r[o + 4] = sky_aerial(sky, aerial_tex, p.xy, Q.q[i].dir.w);
	R.r[o + 5] = sky_multiscatter(sky, multiscatter_tex, p.z, p.w);
	R.r[o + 6] = vec4((i & 1) == 0 ? sky_sun_illuminance(sky, transmittance_tex)
				       : sky_moon_illuminance(sky, transmittance_tex), 0.0);
	R.r[o + 7] = vec4(sky_aerial_screen_uv(sky, dir), 0.0, 0.0);
	R.r[o + 8] = sky_aerial_dir(sky, aerial_tex, dir, Q.q[i].dir.w);
}
