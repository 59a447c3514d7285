#version 450
#extension GL_GOOGLE_include_directive : require
// terrain.frag - the ground: a lambertian albedo lit by the sun and the moon
// through the transmittance from the point (the sun's through the clouds'
// shadow map too), by the sky's irradiance and the sunlight the clouds
// scatter down (skycloud_ground_light); then aerial perspective at its
// distance and the clouds in front, through the GLSL library.
#include "frame.glsl"

layout(location = 0) in vec3 in_eye_km;
layout(location = 1) in vec3 in_normal;
layout(location = 0) out vec4 out_colour;

// Illuminance (lx) of a light in direction dir reaching a point at
// altitude_km, zero once the light is under that point's horizon.
vec3 light_at(vec3 dir, vec3 illuminance, float altitude_km)
{
	if (dir.z < skymap_horizon_cos(F.sky[0].planet.x, altitude_km))
		return vec3(0.0);
	return illuminance * sky_transmittance(F.sky[0], transmittance_tex, altitude_km, dir.z);
}

void main()
{
	vec3 dir;
	if (!view_direction(gl_FragCoord.xy + F.wall.zw, dir))
		discard;		// outside the dome master's circle
	vec3 n = normalize(in_normal);
	float dist = length(in_eye_km);
	vec3 view = in_eye_km / dist;
	float altitude = max(F.sky[0].planet.z + in_eye_km.z, 0.0);
	vec3 sun = light_at(F.sky[0].sun.xyz, F.sky[0].sun_illuminance.rgb, altitude);
	vec2 g = cloud_ground_light(altitude);
	float sky = 0.5 + 0.5 * n.z;	// the share of the sky a slope sees
	vec3 e = sun * (max(dot(n, F.sky[0].sun.xyz), 0.0) * cloud_sun_shadow(in_eye_km) +
			max(F.sky[0].sun.z, 0.0) * g.y * sky) +
		 light_at(F.sky[0].moon.xyz, F.sky[0].moon_illuminance.rgb, altitude) *
		 max(dot(n, F.sky[0].moon.xyz), 0.0) +
		 F.ambient_lx.rgb * sky * g.x;
	vec3 surface = F.terrain.rgb / SKYMAP_PI * e;
	out_colour = vec4(clouds_over(view, dist, apply_aerial(view, dist, surface)), 1.0);
}
