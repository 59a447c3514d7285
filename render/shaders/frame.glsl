// frame.glsl - what skyrender's shaders share: the frame's uniform block
// (the GLSL library's SkyState, then the camera: struct rvk_frame_ubo of
// render/rvk_internal.h), the table images, and the camera of one tile of a
// wall: pixel -> view direction as libsky's sky_render_direction() gives
// it, and a point -> the tile's clip position for the terrain; the clouds
// in front of what a pixel shows (the GLSL library's cloud march).
#include "skycloud_march.glsl"

// The aerial textures: one for a perspective tile or a dome master (a
// volume, or the eye point's panorama), or four volumes, quarters of the
// horizon, for a dome master of volumes (volume k faces yaw + 90 k degrees).
const int MAX_AERIAL = 4;

layout(std140, set = 0, binding = 0) uniform FrameBlock {
	SkyState sky[MAX_AERIAL];	// the same sky, each with its volume's camera
	vec4 wall;		// wall width, height (px); this tile's origin in it (px)
	vec4 tile;		// tile width, height (px); projection (0 perspective, 1 fisheye); tan(vfov / 2)
	vec4 cam_f;		// the wall camera's forward (ENU); w: yaw (rad)
	vec4 cam_r;		// right; w: the wall's aspect
	vec4 cam_u;		// up; w: near plane (km)
	vec4 ambient_lx;	// horizontal sky irradiance; w: disk flags (SKY_DISK_*)
	vec4 terrain;		// the ground's albedo (rgb); w: the number of aerial volumes
	SkycloudLayer layers[SKYCLOUD_MAX_LAYERS];	// the slot's (std140: 80 bytes each)
	SkycloudScene scene;
	SkycloudLight sun;	// with its shadow map's frame (dir.w 1: the map is bound)
	vec4 clouds;		// x: the march's steps (0: no clouds); y: light steps
} F;

layout(set = 0, binding = 1) uniform sampler2D transmittance_tex;
layout(set = 0, binding = 2) uniform sampler2D skyview_tex;
layout(set = 0, binding = 3) uniform sampler2D multiscatter_tex;
layout(set = 0, binding = 4) uniform sampler2D coverage_tex;	// SKY_TABLE_CLOUD
layout(set = 0, binding = 5) uniform sampler2D shadow_tex;	// SKY_TABLE_SHADOW's slice 0: the sun's
layout(set = 0, binding = 6) uniform sampler3D aerial_tex[MAX_AERIAL];

const float HALF_PI = 0.5 * SKYMAP_PI;

bool is_fisheye() { return F.tile.z > 0.5; }

// The aerial perspective of texture k toward view (ENU, the eye's frame),
// a volume or a panorama: sky_aerial_dir reads either by its SkyState's
// panorama_grid.w (a constant index for the sampler array in each branch:
// k differs from fragment to fragment).
vec4 aerial_of(int k, vec3 view, float distance_km)
{
	if (k == 1)
		return sky_aerial_dir(F.sky[1], aerial_tex[1], view, distance_km);
	if (k == 2)
		return sky_aerial_dir(F.sky[2], aerial_tex[2], view, distance_km);
	if (k == 3)
		return sky_aerial_dir(F.sky[3], aerial_tex[3], view, distance_km);
	return sky_aerial_dir(F.sky[0], aerial_tex[0], view, distance_km);
}

// A dome's quarters blend over this many quarters either side of their
// boundary (8 degrees), inside both volumes' frusta (55 degrees either side
// of their axes) and clear of their border froxels, so no seam shows.
const float QUARTER_BLEND = 8.0 / 90.0;

// The aerial perspective toward the unit ENU direction view at distance_km
// (RGB in-scattered, A transmittance) of a dome master of four volumes: the
// quarter (or two) that faces that way.
vec4 aerial_quarters(vec3 view, float distance_km)
{
	float q = (atan(view.x, view.y) - F.cam_f.w) / HALF_PI;
	float kf = floor(q + 0.5), f = q - kf;	// f in [-0.5, 0.5] inside quarter kf
	int k = int(mod(kf, 4.0)), k2 = int(mod(kf + sign(f), 4.0));
	float w = 0.5 * smoothstep(0.5 - QUARTER_BLEND, 0.5, abs(f));
	vec4 a = aerial_of(k, view, distance_km);
	return w > 0.0 ? mix(a, aerial_of(k2, view, distance_km), w) : a;
}

// A surface's radiance seen toward view at distance_km: through the one
// aerial texture (a volume or a panorama: the library's
// sky_apply_aerial_dir), or a dome's quarters.
vec3 apply_aerial(vec3 view, float distance_km, vec3 surface)
{
	if (int(F.terrain.w) != MAX_AERIAL)
		return sky_apply_aerial_dir(F.sky[0], aerial_tex[0], view, distance_km, surface);
	vec4 a = aerial_quarters(view, distance_km);
	return surface * a.a + a.rgb;
}

// The aerial perspective toward view at distance_km, whichever textures
// the frame has.
vec4 aerial_toward(vec3 view, float distance_km)
{
	if (int(F.terrain.w) != MAX_AERIAL)
		return aerial_of(0, view, distance_km);
	return aerial_quarters(view, distance_km);
}

// The clouds between the eye and what the pixel shows toward view at
// far_km (behind: its radiance with its own aerial perspective; 1e30 for
// the sky), composited in the library's order (skycloud_composite): the
// march at the block's steps, the air at the clouds' depth.
vec3 clouds_over(vec3 view, float far_km, vec3 behind)
{
	if (F.clouds.x < 0.5)
		return behind;
	vec3 eye = vec3(0.0, 0.0, F.sky[0].planet.z);
	SkycloudSample c = skycloud_march(F.sky[0], transmittance_tex, multiscatter_tex, coverage_tex, shadow_tex,
					  F.layers, F.scene, F.sun, eye, view, far_km, int(F.clouds.x),
					  int(F.clouds.y), 0.5);
	if (!(c.transmittance < 1.0))
		return behind;
	return skycloud_composite(behind, c, aerial_toward(view, c.depth_km));
}

// The sun's light through the clouds at q (km from the eye): its shadow
// map's transmittance, 1 without clouds or a map.
float cloud_sun_shadow(vec3 q)
{
	if (F.clouds.x < 0.5 || F.sun.dir.w < 0.5)
		return 1.0;
	return skycloud_shadow(shadow_tex, F.sun.frame, q + vec3(0.0, 0.0, F.sky[0].planet.z));
}

// The ground's light under the layers at altitude h_km, as shares of the
// clear sky's (the library's skycloud_ground_light): x of the sky's
// irradiance (the sky the layers leave open and what they let through),
// y of the sun's horizontal irradiance that they scatter down (its beam
// is the shadow map's); 1 and 0 without clouds.
vec2 cloud_ground_light(float h_km)
{
	if (F.clouds.x < 0.5)
		return vec2(1.0, 0.0);
	return skycloud_ground_light(F.layers, F.scene, h_km, F.sun.dir.z);
}

// The unit ENU direction through wall position p (pixels, y down): false
// outside the fisheye's circle. sky_render_direction(), in float.
bool view_direction(vec2 p, out vec3 ret_dir)
{
	vec2 wh = F.wall.xy;
	if (is_fisheye()) {
		float rad = 0.5 * min(wh.x, wh.y);
		vec2 d = vec2(p.x - 0.5 * wh.x, 0.5 * wh.y - p.y) / rad;
		float rho = length(d);
		if (rho > 1.0)
			return false;
		float az = F.cam_f.w + atan(d.x, -d.y), el = HALF_PI * (1.0 - rho);
		ret_dir = vec3(cos(el) * sin(az), cos(el) * cos(az), sin(el));
		return true;
	}
	float t = F.tile.w;
	float sx = (2.0 * p.x / wh.x - 1.0) * t * (wh.x / wh.y), sy = (1.0 - 2.0 * p.y / wh.y) * t;
	ret_dir = normalize(F.cam_f.xyz + sx * F.cam_r.xyz + sy * F.cam_u.xyz);
	return true;
}

// The tile's clip position of point q (km, ENU, from the eye) with reversed
// depth (near / distance: nearer is greater, infinity is 0), and the
// elevation of q for the fisheye's clip plane.
vec4 tile_position(vec3 q, out float ret_elevation)
{
	vec2 wh = F.wall.xy, o = F.wall.zw, tw = F.tile.xy;
	float dist = length(q);
	ret_elevation = atan(q.z, length(q.xy));
	if (is_fisheye()) {
		float rad = 0.5 * min(wh.x, wh.y);
		float rho = 1.0 - ret_elevation / HALF_PI, a = atan(q.x, q.y) - F.cam_f.w;
		vec2 px = 0.5 * wh + rad * rho * vec2(sin(a), cos(a));
		return vec4(2.0 * (px - o) / tw - 1.0, F.cam_u.w / dist, 1.0);
	}
	float t = F.tile.w, aspect = F.cam_r.w;
	float xr = dot(q, F.cam_r.xyz), yu = dot(q, F.cam_u.xyz), zf = dot(q, F.cam_f.xyz);
	// the wall's pixel, times zf, moved to the tile's normalised coordinates
	float x = (xr / (t * aspect) + zf) * (wh.x / tw.x) - (2.0 * o.x / tw.x + 1.0) * zf;
	float y = (zf - yu / t) * (wh.y / tw.y) - (2.0 * o.y / tw.y + 1.0) * zf;
	return vec4(x, y, F.cam_u.w, zf);
}
