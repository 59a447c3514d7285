#version 450
#extension GL_GOOGLE_include_directive : require
// terrain.vert - the height field's vertices, placed under the observer
// (its altitude from the slot) and projected into the tile.
#include "frame.glsl"

layout(location = 0) in vec3 in_position_km;
layout(location = 1) in vec3 in_normal;
layout(location = 0) out vec3 out_eye_km;	// the point from the eye, ENU
layout(location = 1) out vec3 out_normal;

out gl_PerVertex {
	vec4 gl_Position;
	float gl_ClipDistance[1];
};

void main()
{
	vec3 q = in_position_km - vec3(0.0, 0.0, F.sky[0].planet.z);
	float elevation;
	gl_Position = tile_position(q, elevation);
	// The fisheye's projection folds at the nadir: what lies more than 20
	// degrees under the horizon is off the dome anyway, cut it there.
	gl_ClipDistance[0] = is_fisheye() ? elevation + 0.35 : 1.0;
	out_eye_km = q;
	out_normal = in_normal;
}
