// skymap.glsl - the uv mappings of the published tables in GLSL: proto/skymap.h
// function for function, included by skyd's compute shaders and by render
// clients' shaders (through sky.glsl).
//
// Same names, arguments and conventions as skymap.h (lengths in km, angles
// in radians, texel i of n centred at (i + 0.5) / n, rows bottom-up in v),
// in float, returning what skymap.h returns through ret_* (a uv as a vec2).
// test_glsl_map runs every function here on the device and checks it
// against skymap.h at many points; a change to a mapping is made in both
// files and bumps SKYMAP_VERSION. Plain GLSL 4.50 without extensions: no
// bindings, no globals beyond constants.
#ifndef SKYMAP_GLSL
#define SKYMAP_GLSL

// skymap.h's SKYMAP_VERSION, for a client that checks the header's
// uv_mapping_version against the shaders it was built with.
#define SKYMAP_GLSL_VERSION 4

const float SKYMAP_PI = 3.14159265358979;

float skymap_safe_sqrt(float x) { return sqrt(max(x, 0.0)); }

// Exact inverse pair: unit [0, 1] <-> texture coordinate whose ends are the
// centres of the first and the last texel of n.
float skymap_unit_to_tex(float x, int n) { return 0.5 / float(n) + x * (1.0 - 1.0 / float(n)); }
float skymap_tex_to_unit(float u, int n) { return (u - 0.5 / float(n)) / (1.0 - 1.0 / float(n)); }

// rho^2 = r^2 - Rb^2 written as h (2 Rb + h): exact at small altitudes.
float skymap_rho2(float rb, float altitude_km) { return altitude_km * (2.0 * rb + altitude_km); }

// Cosine of the zenith angle of the geometric horizon seen from altitude h.
float skymap_horizon_cos(float rb, float altitude_km)
{
	float h = max(altitude_km, 0.0);
	return -skymap_safe_sqrt(skymap_rho2(rb, h)) / (rb + h);
}

// Bruneton's x_mu along a transmittance row from radius r toward cos-zenith
// mu, from what a row shares: top_c = rt^2 - r^2 (factored, no
// cancellation), d_min = rt - r and inv_range = 1 / (d_max - d_min). The
// distance to the top is skymap_distance_to_top's.
float skymap_transmittance_x(float r, float mu, float top_c, float d_min, float inv_range)
{
	mu = clamp(mu, -1.0, 1.0);
	float d = max(-r * mu + skymap_safe_sqrt(r * r * mu * mu + top_c), 0.0);
	return (d - d_min) * inv_range;
}

// Distance from altitude h along cos-zenith mu to the top sphere (rt), for
// a point inside it; >= 0.
float skymap_distance_to_top(float rb, float rt, float altitude_km, float mu)
{
	float shell = rt - rb;
	float top_c = (shell - altitude_km) * (2.0 * rb + shell + altitude_km);
	return skymap_transmittance_x(rb + altitude_km, mu, top_c, 0.0, 1.0);
}

// Transmittance table (Bruneton 2017): (altitude, mu) -> uv, for rays that
// do not hit the ground.
vec2 skymap_transmittance_uv(float rb, float rt, float altitude_km, float mu, int w, int h)
{
	float shell = rt - rb;
	float alt = clamp(altitude_km, 0.0, shell);
	float H = skymap_safe_sqrt(shell * (rt + rb));
	float rho = skymap_safe_sqrt(skymap_rho2(rb, alt));
	float d_min = shell - alt, d_max = rho + H;
	float top_c = (shell - alt) * (2.0 * rb + shell + alt);
	float x_mu = skymap_transmittance_x(rb + alt, mu, top_c, d_min,
					    d_max > d_min ? 1.0 / (d_max - d_min) : 0.0);
	return vec2(skymap_unit_to_tex(clamp(x_mu, 0.0, 1.0), w),
		    skymap_unit_to_tex(clamp(rho / H, 0.0, 1.0), h));
}

// The exact inverse: uv -> (altitude, mu).
vec2 skymap_transmittance_inverse(float rb, float rt, vec2 uv, int w, int h)
{
	float x_mu = skymap_tex_to_unit(uv.x, w), x_r = skymap_tex_to_unit(uv.y, h);
	float H = skymap_safe_sqrt((rt - rb) * (rt + rb));
	float rho = H * x_r;
	float r = sqrt(rho * rho + rb * rb);
	float alt = rho * rho / (r + rb);
	float d_min = (rt - rb) - alt, d_max = rho + H;
	float d = d_min + x_mu * (d_max - d_min);
	float mu = d <= 0.0 ? 1.0 : (H * H - rho * rho - d * d) / (2.0 * r * d);
	return vec2(alt, clamp(mu, -1.0, 1.0));
}

// Multi-scattering table's unit u for mu_s on the row whose horizon cosine
// is mh, given inv_below = 1 / (1 + mh) and inv_above = 1 / (1 - mh) (a row
// shares them): with s = (mu_s - mh) / (1 + mh) below the horizon,
// (mu_s - mh) / (1 - mh) above, u = 0.5 + 0.5 sign(s) sqrt(|s|).
float skymap_multiscatter_x(float mu_s, float mh, float inv_below, float inv_above)
{
	float d = clamp(mu_s, -1.0, 1.0) - mh;
	float sn = clamp(d * (d < 0.0 ? inv_below : inv_above), -1.0, 1.0);
	return 0.5 + 0.5 * sign(sn) * sqrt(abs(sn));
}

// Multi-scattering table: v = altitude / shell, u packs texels around the
// horizon of that altitude (skymap.h says why).
vec2 skymap_multiscatter_uv(float rb, float rt, float altitude_km, float mu_s, int w, int h)
{
	float alt = clamp(altitude_km, 0.0, rt - rb);
	float mh = skymap_horizon_cos(rb, alt);
	float x = skymap_multiscatter_x(mu_s, mh, 1.0 / (1.0 + mh), 1.0 / (1.0 - mh));
	return vec2(skymap_unit_to_tex(x, w), skymap_unit_to_tex(alt / (rt - rb), h));
}

// The inverse: uv -> (altitude, mu_s).
vec2 skymap_multiscatter_inverse(float rb, float rt, vec2 uv, int w, int h)
{
	float alt = clamp(skymap_tex_to_unit(uv.y, h), 0.0, 1.0) * (rt - rb);
	float a = 2.0 * skymap_tex_to_unit(uv.x, w) - 1.0, sn = a * abs(a);
	float mh = skymap_horizon_cos(rb, alt);
	return vec2(alt, clamp(mh + sn * (sn < 0.0 ? 1.0 + mh : 1.0 - mh), -1.0, 1.0));
}

// The horizon's zenith angle acos(horizon_cos), as pi/2 plus the small
// angle below the horizontal: GPU acos is approximate near the result's
// scale (Mesa's errs by 1e-4 rad), atan of a small ratio keeps its relative
// precision.
float skymap_horizon_rad(float horizon_cos)
{
	float c = clamp(horizon_cos, -1.0, 1.0);
	return 0.5 * SKYMAP_PI + atan(-c, skymap_safe_sqrt((1.0 - c) * (1.0 + c)));
}

// Sky-view table: u = azimuth / 2 pi (eastward from north, periodic: sample
// it with a repeating address mode), v packs texels at the horizon, whose
// zenith angle comes from horizon_cos (skymap_horizon_cos at the observer).
vec2 skymap_skyview_uv(float horizon_cos, float view_zenith_rad, float azimuth_rad, int h)
{
	float th = skymap_horizon_rad(horizon_cos);
	float t = clamp(view_zenith_rad, 0.0, SKYMAP_PI), x;
	if (t < th)
		x = 0.5 * (1.0 - skymap_safe_sqrt(1.0 - t / th));
	else
		x = 0.5 + 0.5 * skymap_safe_sqrt((t - th) / (SKYMAP_PI - th));
	float a = azimuth_rad / (2.0 * SKYMAP_PI);
	return vec2(a - floor(a), skymap_unit_to_tex(x, h));
}

// skymap_skyview_uv for a view direction (unit, ENU), from the horizon's
// cos-zenith, sin-zenith and zenith angle (horizon_cos, horizon_sin,
// horizon_rad) taken in double on the CPU. Shaders use this form: GPU
// inverse trigonometry is approximate (Vulkan allows 4096 ulp for atan;
// Mesa's is good to about 1e-5 rad), and the latitude's square root at the
// horizon turns an error e of the view's angle from the horizon into
// sqrt(e) of v. Here that angle is atan(sin, cos) of the difference, whose
// error shrinks with it, and the azimuth alone goes through atan whole.
vec2 skymap_skyview_uv_dir(float horizon_cos, float horizon_sin, float horizon_rad, vec3 dir, int h)
{
	float s = length(dir.xy);
	// The view's zenith angle less the horizon's, in (-pi, pi).
	float dt = atan(s * horizon_cos - dir.z * horizon_sin, s * horizon_sin + dir.z * horizon_cos);
	float x = dt < 0.0 ? 0.5 * (1.0 - skymap_safe_sqrt(min(-dt / horizon_rad, 1.0)))
			   : 0.5 + 0.5 * skymap_safe_sqrt(min(dt / (SKYMAP_PI - horizon_rad), 1.0));
	float a = atan(dir.x, dir.y) / (2.0 * SKYMAP_PI);
	return vec2(a - floor(a), skymap_unit_to_tex(x, h));
}

// The inverse: uv -> (view zenith, azimuth).
vec2 skymap_skyview_inverse(float horizon_cos, vec2 uv, int h)
{
	float th = skymap_horizon_rad(horizon_cos);
	float x = clamp(skymap_tex_to_unit(uv.y, h), 0.0, 1.0), zenith;
	if (x < 0.5) {
		float a = 1.0 - 2.0 * x;
		zenith = th * (1.0 - a * a);
	} else {
		float a = 2.0 * x - 1.0;
		zenith = th + (SKYMAP_PI - th) * a * a;
	}
	return vec2(zenith, 2.0 * SKYMAP_PI * uv.x);
}

// Aerial perspective: slice k (0-based) of n holds the integral from the
// camera to depth range ((k + 1) / n)^p, p = 2 squared, 1 linear.
float skymap_aerial_depth_km(int k, int n, float range_km, bool squared)
{
	float x = float(k + 1) / float(n);
	return range_km * (squared ? x * x : x);
}

// Continuous slice coordinate of a depth: -1 at depth 0, k at the far edge
// of slice k.
float skymap_aerial_slice(float depth_km, int n, float range_km, bool squared)
{
	float x = clamp(depth_km / range_km, 0.0, 1.0);
	return (squared ? sqrt(x) : x) * float(n) - 1.0;
}

// A panorama of an eye point (struct sky_shm_panorama): the texture
// coordinates of the direction (azimuth east of north, elevation). Columns
// azimuth0 + i * step, the last repeating the first with full_circle, else
// an arc whose nearer end serves directions outside it; rows in x =
// sign(e) sqrt(|e|), e the elevation above horizon_rad.
vec2 skymap_panorama_uv(float azimuth0_rad, float azimuth_step_rad, float row0, float row_step,
			float horizon_rad, int width, int height, bool full_circle, float azimuth_rad,
			float elevation_rad)
{
	const float two_pi = 2.0 * SKYMAP_PI;
	float du = azimuth_rad - azimuth0_rad;
	du -= two_pi * floor(du / two_pi);
	if (!full_circle) {
		float span = azimuth_step_rad * float(width - 1);
		if (du > span)
			du = du - span < two_pi - du ? span : 0.0;
	}
	float f = clamp(du / azimuth_step_rad, 0.0, float(width - 1));
	float e = elevation_rad - horizon_rad;
	float x = e < 0.0 ? -sqrt(-e) : sqrt(e);
	float g = clamp((x - row0) / row_step, 0.0, float(height - 1));
	return vec2((f + 0.5) / float(width), (g + 0.5) / float(height));
}

#endif
