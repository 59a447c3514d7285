// msgrid.glsl - the multi-scattering passes' shared geometry: each texel's
// altitude and sun angles (skymap.h's mapping), and the direction grid over
// which multiscatter.comp integrates L2 and f_ms and msiterate.comp gathers
// the neighbourhood's light. The two must use the same quadrature:
// msiterate recovers L2 = psi (1 - f_ms) from the table on its first step.
// Included after common.glsl.

layout(constant_id = SPEC_MS_DIRS) const int MS_DIRS = 64;
// The 64-direction grid: 16 rings of cos-zenith by 4 azimuth columns. A
// ray's path through the shell depends on its zenith angle only, and near
// the horizon that path grows tenfold within a few degrees, so the rings
// carry most of the quadrature's error and get most of the directions. The
// ring edges are mu = sign(s) |s|^MS_RING_POW for s uniform in [-1, 1]
// (ring_edge()): the rings at the horizon are 0.66 of the mean cell's solid
// angle, those at the zenith and nadir 1.18 of it, each weighted by its
// exact solid angle. The grids and powers compared are in
// docs/findings/shaders.md; skybench accuracy measures it and test_msgrid
// checks the rings' weights.
const int MS_RINGS = 16, MS_COLS = 4, MS_HALF_COLS = MS_COLS / 2;
const float MS_RING_POW = 1.2;
layout(constant_id = SPEC_MS_SUN_GROUP) const int MS_SUN_GROUP = 4;
// The grain (daemon/engine/eng_grain.c): 1, each invocation marching every
// cell in turn for MS_SUN_GROUP texels of a row (a CPU device, where a
// barrier turns every invocation into a coroutine); or the cells marched,
// one lane each, a workgroup per texel and MS_SUN_GROUP 1 (a GPU: 1024
// workgroups at the default size, where the CPU grain made 4). The passes'
// workgroup size is (SPEC_LOCAL_X, SPEC_LOCAL_Y): 8 x 8, or MS_LANES x 1.
layout(constant_id = SPEC_MS_LANES) const int MS_LANES = 1;
layout(local_size_x_id = SPEC_LOCAL_X, local_size_y_id = SPEC_LOCAL_Y) in;

// The cosine of ring edge e (0: zenith, MS_RINGS: nadir).
float ring_edge(int e)
{
	float s = 1.0 - 2.0 * float(e) / float(MS_RINGS);
	return sign(s) * pow(abs(s), MS_RING_POW);
}

// Marched direction k's ring: its top and bottom cosines.
vec2 cell_ring(int k)
{
	if (MS_DIRS == 2)
		return k == 0 ? vec2(1.0, 0.0) : vec2(0.0, -1.0);
	int ring = k / MS_HALF_COLS;
	return vec2(ring_edge(ring), ring_edge(ring + 1));
}

// Marched direction k's cell's solid angle over the mean cell's.
float cell_weight(vec2 ring)
{
	return MS_DIRS == 2 ? 1.0 : (ring.x - ring.y) * float(MS_RINGS) * 0.5;
}

// Marched direction k at the middle of its ring's cosines, azimuth column
// k % MS_HALF_COLS of MS_COLS: phi in (0, pi); for 2 directions straight up
// and down.
vec3 cell_direction(int k, vec2 ring)
{
	if (MS_DIRS == 2)
		return vec3(0.0, 0.0, k == 0 ? 1.0 : -1.0);
	float ct = 0.5 * (ring.x + ring.y);
	float ph = 2.0 * PI * (float(k % MS_HALF_COLS) + 0.5) / float(MS_COLS);
	float st = safe_sqrt(1.0 - ct * ct);
	return vec3(st * cos(ph), st * sin(ph), ct);
}

// The density of each constituent at altitude h (0 past N_CONST).
vec4 densities(float h)
{
	vec4 d = vec4(0.0);
	for (int i = 0; i < N_CONST; i++)
		d[i] = density(i, h);
	return d;
}

// Row py's altitude in km.
float ms_row_altitude(int py)
{
	return clamp(tex_to_unit((float(py) + 0.5) / float(OUT_H), OUT_H), 0.0, 1.0) * P.SHELL_KM;
}

// The suns (in the x-z plane) of texels x0 .. x0 + MS_SUN_GROUP - 1 of the
// row at altitude h: skymap.h's u packs texels around the horizon of the
// altitude. Texels past the row repeat its last.
void ms_row_suns(int x0, float h, out vec3 ret_sun[MS_SUN_GROUP])
{
	float mh = horizon_cos(h);
	for (int j = 0; j < MS_SUN_GROUP; j++) {
		int px = min(x0 + j, OUT_W - 1);
		float a_mu = 2.0 * tex_to_unit((float(px) + 0.5) / float(OUT_W), OUT_W) - 1.0;
		float sn = a_mu * abs(a_mu);
		float mu_s = clamp(mh + sn * (sn < 0.0 ? 1.0 + mh : 1.0 - mh), -1.0, 1.0);
		ret_sun[j] = vec3(safe_sqrt(1.0 - mu_s * mu_s), 0.0, mu_s);
	}
}

// The weight of a direction's cell in the mean over the sphere: 2 / 64
// (the directions at -phi are not marched), or 1 / 2 for 2 directions.
const int MS_MARCHED = SKY_MS_MARCHED(MS_DIRS);	// MS_RINGS * MS_HALF_COLS, or 2
const float MS_NORM = MS_DIRS == 2 ? 0.5 : 2.0 / float(MS_RINGS * MS_COLS);

// The cells an invocation keeps a value of (cell_slot(): the CPU grain
// every marched cell, a lane its own).
const int MS_KEPT = MS_LANES > 1 ? 1 : 32;

int cell_slot(int k)
{
	return MS_LANES > 1 ? 0 : k;
}

// The invocation's texels: the first of its row group (x), its row (y) and
// its lane, which is the first cell it marches (z); it marches every
// MS_LANES-th cell from there. The CPU grain's rows are interleaved
// (interleaved_row()): a row's cost grows with its altitude.
ivec3 ms_texels()
{
	if (MS_LANES > 1)
		return ivec3(gl_WorkGroupID.xy, gl_LocalInvocationID.x);
	return ivec3(int(gl_GlobalInvocationID.x) * MS_SUN_GROUP, interleaved_row(int(gl_GlobalInvocationID.y), OUT_H), 0);
}

// The wide grain's sums over the cells: each lane puts the n parts it
// summed over its own cell into shared memory, then for each part one lane
// adds the cells' values in cell order, as the CPU grain's loop over the
// cells does, and every lane reads the totals back into v. Bit for bit the
// CPU grain's sums where the compiler fuses no multiply into them (a fused
// multiply-add rounds once where a lane's part is rounded before the add;
// tests/numerical/test_grain.c states the bound). Every lane must call it:
// it holds two barriers.
const int MS_PARTS = 26;
shared float ms_parts[MS_PARTS * MS_LANES];
shared float ms_totals[MS_PARTS];

void ms_reduce(inout float v[MS_PARTS], int n, int lane)
{
	for (int q = 0; q < n; q++)
		ms_parts[q * MS_LANES + lane] = v[q];
	barrier();
	for (int q = lane; q < n; q += MS_LANES) {
		float sum = 0.0;
		for (int k = 0; k < MS_MARCHED; k++)
			sum += ms_parts[q * MS_LANES + k];
		ms_totals[q] = sum;
	}
	barrier();
	for (int q = 0; q < n; q++)
		v[q] = ms_totals[q];
}

// A, the ground's first bounce's share of psi, weighs the channels by
// luminance (Rec. 709): one grey share for the three.
const vec3 MS_SHARE_LUM = vec3(0.2126, 0.7152, 0.0722);
