// multiscatter.comp - Hillaire's infinite-order isotropic multiple scattering,
// psi_ms = L2 / (1 - f_ms). Directions: 64 on a grid of 16 rings, denser
// near the horizon, by 4 azimuths, or 2 (straight up and down). For a
// forward-peaked phase (MOMENT_CONST) also the shape of that light from L2's
// moments (MomentBuf); with delta-M (DELTA_CONST, delta_source in
// common.glsl) the table is the scaled medium's instead.
//
// The rays from a point at altitude h do not depend on the sun, so one
// invocation marches them once for MS_SUN_GROUP texels of a row (sun angles)
// and only the light lookups are per texel. The sun lies in the x-z plane,
// so the grid's directions at azimuth phi and -phi contribute alike: half of
// them are marched, counted twice. That is the CPU grain: no shared memory
// and no barrier, since on lavapipe a barrier turns every invocation into a
// coroutine. On a GPU (MS_LANES > 1, msgrid.glsl) a workgroup computes one
// texel, a lane per cell, and the cells' sums meet in shared memory
// (ms_reduce()).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "msgrid.glsl"

// The cosines of the 2 x 2 equal-area sub-samples of marched direction k's
// cell (ring from cosine ring.x down to ring.y): ret_cp * sun.x + ret_ct *
// sun.z is their cosine to a sun in the x-z plane. Cells: ring
// k / MS_HALF_COLS by azimuth column k % MS_HALF_COLS (of MS_COLS), or for 2
// directions the upper and lower hemispheres. Shared by the constituents
// and the suns (cos and sqrt were most of the phase cost). ret_xy2: their
// x^2 - y^2 (the band-2 harmonic of azimuth 2 phi, the shape's).
void cell_subsamples(int k, vec2 ring, out vec4 ret_cp, out vec4 ret_ct, out vec4 ret_xy2)
{
	float col = float(MS_DIRS == 2 ? 0 : k % MS_HALF_COLS);
	float dphi = MS_DIRS == 2 ? 2.0 * PI : 2.0 * PI / float(MS_COLS);
	vec2 ct = mix(ring.xx, ring.yy, vec2(0.25, 0.75));
	vec2 st = sqrt(max(1.0 - ct * ct, 0.0));
	vec2 phi = dphi * (col + vec2(0.25, 0.75));
	vec2 cphi = cos(phi), c2phi = cos(2.0 * phi);
	ret_cp = vec4(st.x * cphi, st.y * cphi);
	ret_ct = vec4(ct.xx, ct.yy);
	ret_xy2 = vec4(st.x * st.x * c2phi, st.y * st.y * c2phi);
}

// phase() for four cosines at once.
vec4 phase4(int kind, float g, vec4 mu)
{
	return vec4(phase(kind, g, mu.x), phase(kind, g, mu.y), phase(kind, g, mu.z),
		    phase(kind, g, mu.w));
}

// The sunlight reaching a point toward mu (light_transmittance), or with
// delta-M the scaled medium's: the disk's visible part times
// exp(-tau'), tau' = ext_scaled * columns_at().
vec3 sunlight(TAlt a, float mu, float radius_rad, mat4x3 ext_scaled)
{
	if (DELTA_CONST < 0)
		return light_transmittance(a, mu, radius_rad);
	float vis = light_visible(a, mu, radius_rad);
	return vis > 0.0 ? vis * exp(-(ext_scaled * columns_at(a, mu))) : vec3(0.0);
}

// What one invocation keeps across its row's cells, per marched cell k,
// constituent i and sun j: the cell's mean phase (cell_sum), the lobe
// constituent's x^2 - y^2 across it (cell_xy2, delta-M only) and the
// normalisation that makes the cells' phases integrate to 1 (phase_norm).
// Module-scope, so that the functions below share them without copies;
// indexed by cell_slot(k) (msgrid.glsl).
float cell_sum[MS_KEPT * 4 * MS_SUN_GROUP];	// MS_MARCHED <= 32 cells
float cell_xy2[MS_KEPT * MS_SUN_GROUP];
float phase_norm[4][MS_SUN_GROUP];

// The sums over the marched cells: L2 and the ground's first bounce per sun,
// L2's first moments (x toward the sun's azimuth, z up) and second moments
// (zz, xz and, from the sub-samples, xx - yy) for the shape, and 1 - f_ms
// as what leaves or is absorbed (sum_escape) with the ground's share of it.
vec3 sum_l2[MS_SUN_GROUP], sum_ground[MS_SUN_GROUP];
vec2 sum_moment[MS_SUN_GROUP];
vec3 sum_second[MS_SUN_GROUP];
vec3 sum_escape, sum_returned;
// Rayleigh's band 2 (a lobe constituent of g1 = 0): the scattering transfer
// int sigma_s T dt of each cell (the field an isotropic source psi sends to
// the point from there, the higher orders' direction) with its zz and xz
// moments, per channel: (transfer, zz, xz).
mat3 sum_transfer;

// L2's first scattering (at y, from the sun toward x) takes each
// constituent's own phase, not the isotropic one: a forward lobe toward a
// low sun lies along long near-horizontal paths that the isotropic phase
// undercounts. A point value is a poor quadrature of such a lobe over a
// 0.2 sr cell, so each cell takes its 2 x 2 sub-samples' mean, normalised
// so that the cells' phases sum to exactly 1 over the sphere and no energy
// is made or lost. Fills cell_sum, cell_xy2 and phase_norm for the suns,
// of the cells from lane on (ms_texels()).
void cell_phases(vec3 sun[MS_SUN_GROUP], int lane)
{
	float total[4][MS_SUN_GROUP];
	for (int i = 0; i < 4; i++)
		for (int j = 0; j < MS_SUN_GROUP; j++)
			total[i][j] = 0.0;
	int k = lane;	// do-while, as in main()
	do {
		vec4 cp, ct, xy2;
		vec2 ring = cell_ring(k);
		float wk = cell_weight(ring);
		cell_subsamples(k, ring, cp, ct, xy2);
		for (int j = 0; j < MS_SUN_GROUP; j++) {
			vec4 mu = cp * sun[j].x + ct * sun[j].z;
			for (int i = 0; i < N_CONST; i++) {
				if (phase_kind(i) == 0)
					continue;
				bool truncated = i == DELTA_CONST;
				vec4 p = phase4(truncated ? 3 : phase_kind(i),
						truncated ? P.c[i].DELTA_G : P.c[i].PHASE_G, mu);
				float c = dot(p, vec4(0.25));
				if (i == MOMENT_CONST)	// only delta-M uses it (store_shape())
					cell_xy2[cell_slot(k) * MS_SUN_GROUP + j] = truncated ? dot(p, xy2) / max(4.0 * c, 1e-30) : 0.0;
				cell_sum[(cell_slot(k) * 4 + i) * MS_SUN_GROUP + j] = c;
				total[i][j] += wk * c;
			}
		}
	} while ((k += MS_LANES) < MS_MARCHED);
	if (MS_LANES > 1) {
		float v[MS_PARTS];
		for (int i = 0; i < 4; i++)
			v[i] = total[i][0];
		ms_reduce(v, N_CONST, lane);
		for (int i = 0; i < 4; i++)
			total[i][0] = v[i];
	}
	for (int i = 0; i < N_CONST; i++)
		for (int j = 0; j < MS_SUN_GROUP; j++)
			phase_norm[i][j] = 1.0 / (4.0 * PI * MS_NORM * max(total[i][j], 1e-30));
}

// The cells marched together: a ring's MS_HALF_COLS cells share their
// zenith angle, so their rays cross the same altitudes at the same
// distances, and the medium along them (densities, steps' weights, the
// lookups' rows) is evaluated once for both; only the lights' cosines
// differ. The CPU grain marches a ring at a time; a lane of the wide
// grain, and the 2-direction grid (two rings of one cell), one cell.
const int MS_TOGETHER = MS_LANES == 1 && MS_DIRS != 2 ? MS_HALF_COLS : 1;

// Adds cell k's L2 (l2, per sun), moments, ground bounce and escape to the
// sums, from its march: the transmittance to its end (tr), what was
// absorbed and scattered on the way, its direction and where it ends.
void add_cell(int k, vec3 dir, float wk, vec3 l2[MS_SUN_GROUP], vec3 tr, vec3 absorbed, vec3 transfer,
	      bool ground, float t_end, float r0, vec3 sun[MS_SUN_GROUP], mat4x3 ext_scaled)
{
	// The cell's solid angle over the mean cell's: every term below is
	// linear in these four.
	tr *= wk;
	absorbed *= wk;
	for (int j = 0; j < MS_SUN_GROUP; j++)
		sum_l2[j] += wk * l2[j];
	// The moments take the cell's weight as L2 does, so that they
	// integrate over the sphere with psi's quadrature.
	if (MOMENT_CONST >= 0) {
		transfer *= wk;
		sum_transfer += mat3(transfer, transfer * (dir.z * dir.z), transfer * (dir.x * dir.z));
	}
	if (MOMENT_CONST >= 0)
		for (int j = 0; j < MS_SUN_GROUP; j++) {
			float l = wk * dot(l2[j], MS_SHARE_LUM);
			sum_moment[j] -= dir.xz * l;
			sum_second[j] += vec3(dir.z * dir.z, dir.x * dir.z, cell_xy2[cell_slot(k) * MS_SUN_GROUP + j]) * l;
		}
	vec3 returned = vec3(0.0);
	if (ground && !GROUND_BLACK) {
		// Lambertian ground lit by the sun: albedo / pi times the cosine.
		vec3 n = vec3(dir.xy * t_end, r0 + dir.z * t_end) / P.BOTTOM_RADIUS_KM;
		TAlt a = t_alt(0.0);
		for (int j = 0; j < MS_SUN_GROUP; j++) {
			float mu_g = dot(n, sun[j]);
			// The sun as a point (radius 0), as transmittance_at() takes it.
			sum_ground[j] += tr * sunlight(a, mu_g, 0.0, ext_scaled) * max(mu_g, 0.0) * P.albedo.rgb / PI;
		}
		// Under the isotropic field psi the Lambertian ground sends back
		// albedo times psi: a transfer like scattering, so every order
		// bounces off the ground, not only the second.
		returned = tr * P.albedo.rgb;
	}
	sum_escape += tr - returned + absorbed;
	sum_returned += returned;
}

// Marches cells k0 .. k0 + MS_TOGETHER - 1 (one ring) from altitude h (r0 =
// Rb + h) and adds them to the sums in cell order. scattering_of,
// absorption_of: the constituents' coefficients as matrices, times the
// step's densities the medium.
void march_cells(int k0, float h, float r0, vec3 sun[MS_SUN_GROUP], mat4x3 ext_scaled, mat4x3 scattering_of,
		 mat4x3 absorption_of)
{
	vec2 ring = cell_ring(k0);
	float wk = cell_weight(ring);
	vec3 dir[MS_TOGETHER];
	for (int c = 0; c < MS_TOGETHER; c++)
		dir[c] = cell_direction(k0 + c, ring);
	float tg, t_end = distance_to_top(h, dir[0].z);
	bool ground = hits_ground(h, dir[0].z, tg);
	if (ground)
		t_end = tg;
	float dt = t_end / float(STEPS);
	vec3 tr = vec3(1.0), absorbed = vec3(0.0), transfer = vec3(0.0);
	// Per cell and sun, the phase-weighted scattering per unit density of
	// each constituent: a matrix times the step's densities (arrays of
	// constituents indexed in loops leave the registers on lavapipe).
	mat4x3 phased_of[MS_TOGETHER * MS_SUN_GROUP];
	for (int j = 0; j < MS_TOGETHER * MS_SUN_GROUP; j++)
		phased_of[j] = mat4x3(0.0);
	for (int i = 0; i < N_CONST; i++) {
		if (phase_kind(i) == 0)
			continue;
		for (int c = 0; c < MS_TOGETHER; c++)
			for (int j = 0; j < MS_SUN_GROUP; j++)
				phased_of[c * MS_SUN_GROUP + j][i] = P.c[i].scattering.rgb *
					(cell_sum[(cell_slot(k0 + c) * 4 + i) * MS_SUN_GROUP + j] * phase_norm[i][j]);
	}
	vec3 l2[MS_TOGETHER * MS_SUN_GROUP];
	for (int j = 0; j < MS_TOGETHER * MS_SUN_GROUP; j++)
		l2[j] = vec3(0.0);
	// do-while: lavapipe runs one more step, every lane off, to end a
	// for loop (STEPS >= 1).
	int s = 0;
	do {
		float t = (float(s) + 0.5) * dt, rr;
		float hs = altitude_along(h, dir[0].z, t, rr);
		vec4 dens = densities(hs);
		vec3 scattering = scattering_of * dens, absorption = absorption_of * dens;
		vec3 step_t, w = tr * step_weight(scattering + absorption, dt, step_t);
		TAlt a = t_alt(hs);
		for (int c = 0; c < MS_TOGETHER; c++) {
			vec3 up = vec3(dir[c].xy * t, r0 + dir[c].z * t) / rr;
			for (int j = 0; j < MS_SUN_GROUP; j++)
				l2[c * MS_SUN_GROUP + j] += w * (phased_of[c * MS_SUN_GROUP + j] * dens) *
							    sunlight(a, dot(up, sun[j]), P.SUN_RADIUS_RAD, ext_scaled);
		}
		absorbed += w * absorption;
		transfer += w * scattering;
		tr *= step_t;
	} while (++s < STEPS);
	for (int c = 0; c < MS_TOGETHER; c++) {
		vec3 l2_cell[MS_SUN_GROUP];
		for (int j = 0; j < MS_SUN_GROUP; j++)
			l2_cell[j] = l2[c * MS_SUN_GROUP + j];
		add_cell(k0 + c, dir[c], wk, l2_cell, tr, absorbed, transfer, ground, t_end, r0, sun, ext_scaled);
	}
}

// The shape of the multiply scattered light for ms_source, texel i of sun
// j, from L2's moments in the frame of the sun's vertical plane (x toward
// the sun's azimuth, z up), relative to psi (msiterate.comp rescales it as
// psi grows, like A): the texel holds (3 m_z, 5 <P2(w_z)>, z, a).
// - a: the share of the sun's aureole, a Henyey-Greenstein lobe of
//   parameter k = g1 about the sunlight, which carries the flux toward the
//   sun's side (m_x = -a k sin(theta_s));
// - 3 m_z: band 1 of the vertical flux (m the net over the scalar flux);
// - 5 <P2(w_z)>: band 2 about the vertical, the horizon's brightness;
// - z: with delta-M 3.75 (T_xx - T_yy), how much of the light lies in the
//   sun's vertical plane rather than across it, from the cells'
//   sub-samples (cell_xy2) less the aureole's own part a k^2 sin^2(theta_s);
//   without delta-M the sub-samples cannot resolve the phase's narrow peak
//   and z is 15 T_xz. One texel keeps a lookup to one fetch.
// With a forward lobe L2's shape stands for the higher orders' too.
// Rayleigh's (g1 = 0: bands 0 and 2 only) takes the whole field, L2 plus the
// higher orders psi times each direction's transfer (sum_transfer): they
// arrive far more from the horizon than L2. Only where the sun is up (lit):
// in the earth's shadow psi along a path is not the point's, and the shape
// read twilight skies high (docs/findings/shaders.md, "The horizon reads
// blue low").
// docs/physics.md derives the bands; docs/findings/shaders.md has the variants
// measured on Mars.
void store_shape(int i, int j, vec3 psi, vec3 sun_j, float escape_lum, float lit)
{
	float l = max(dot(sum_l2[j], MS_SHARE_LUM), 1e-30);
	float share = l * MS_NORM / escape_lum / max(dot(psi, MS_SHARE_LUM), 1e-30);
	vec2 m = sum_moment[j] / l;
	vec3 t = sum_second[j] / l;
	float k = DELTA_CONST >= 0 ? P.c[max(DELTA_CONST, 0)].DELTA_G	// the truncated phase's g'
				   : P.c[max(MOMENT_CONST, 0)].PHASE_G1;
	if (k == 0.0) {
		float field = l + dot(psi * sum_transfer[0], MS_SHARE_LUM);
		t.xy = (sum_second[j].xy + vec2(dot(psi * sum_transfer[1], MS_SHARE_LUM),
						dot(psi * sum_transfer[2], MS_SHARE_LUM))) / field;
		share = field * MS_NORM / max(dot(psi, MS_SHARE_LUM), 1e-30) * lit;
	}
	float a = clamp(-m.x / max(k * sun_j.x, 1e-3), 0.0, 1.0);
	float z = DELTA_CONST >= 0 ? 3.75 * (t.z - a * k * k * sun_j.x * sun_j.x) : 15.0 * t.y;
	MOB.d[i] = share * vec4(3.0 * m.y, 7.5 * t.x - 2.5, z, a);
}

// Under a Rayleigh lobe, where the sun is up: the higher orders' transfer
// beyond Hillaire's isotropic f_ms. Light scattered from a field brighter
// toward the horizon (<P2> < 0) leaves again more along the long
// horizontal paths, where more of it scatters: f_eff = f + 5 g2 <P2>
// <f P2>, with g2 the medium's at the point (sum sigma_i g2_i / sigma_s)
// and <P2> the field's of store_shape (from the first psi). Returns
// f_eff - f per channel (docs/findings/shaders.md, "The horizon reads blue
// low").
vec3 band2_transfer(int j, float h, vec3 psi, vec3 sun_j)
{
	float l = max(dot(sum_l2[j], MS_SHARE_LUM), 1e-30);
	float field = l + dot(psi * sum_transfer[0], MS_SHARE_LUM);
	float p2 = 1.5 * (sum_second[j].x + dot(psi * sum_transfer[1], MS_SHARE_LUM)) / field - 0.5;
	vec3 fp2 = (1.5 * sum_transfer[1] - 0.5 * sum_transfer[0]) * MS_NORM;
	Scatter sc;
	medium_parts(h, sc);
	vec3 s0 = vec3(0.0), s2 = vec3(0.0);
	for (int i = 0; i < N_CONST; i++) {
		s0 += sc.s[i];
		s2 += sc.s[i] * P.c[i].PHASE_G2;
	}
	return 5.0 * s2 / max(s0, vec3(1e-30)) * p2 * fp2 * light_visible(t_alt(h), sun_j.z, P.SUN_RADIUS_RAD);
}

// The wide grain: the sums over every lane's cells (a texel's one sun);
// the shape's moments only where there is a shape.
void reduce_cells(int lane)
{
	float v[MS_PARTS];
	for (int c = 0; c < 3; c++) {
		v[c] = sum_l2[0][c];
		v[3 + c] = sum_ground[0][c];
		v[6 + c] = sum_escape[c];
		v[9 + c] = sum_returned[c];
		v[12 + c] = sum_second[0][c];
		for (int m = 0; m < 3; m++)
			v[15 + 3 * m + c] = sum_transfer[m][c];
	}
	v[24] = sum_moment[0].x;
	v[25] = sum_moment[0].y;
	ms_reduce(v, MOMENT_CONST >= 0 ? MS_PARTS : 12, lane);
	for (int c = 0; c < 3; c++) {
		sum_l2[0][c] = v[c];
		sum_ground[0][c] = v[3 + c];
		sum_escape[c] = v[6 + c];
		sum_returned[c] = v[9 + c];
		sum_second[0][c] = v[12 + c];
		for (int m = 0; m < 3; m++)
			sum_transfer[m][c] = v[15 + 3 * m + c];
	}
	sum_moment[0] = vec2(v[24], v[25]);
}

void main()
{
	load_params();
	// Delta-M (delta_source in common.glsl): the table is the scaled
	// medium's, whose DELTA_CONST scatters (1 - f) sigma_D through p' and
	// whose sunlight comes through T_l' = exp(-(ext' * columns_at())).
	if (DELTA_CONST >= 0)
		P.c[max(DELTA_CONST, 0)].scattering.rgb -= delta_removed();
	// The scaled extinctions, times columns_at() the scaled optical depth.
	mat4x3 ext_scaled = mat4x3(0.0);
	for (int i = 0; i < N_CONST; i++)
		ext_scaled[i] = P.c[i].scattering.rgb + P.c[i].absorption.rgb;
	ivec3 at = ms_texels();
	int x0 = at.x, py = at.y, lane = at.z;
	if (x0 >= OUT_W || py >= OUT_H)
		return;

	float h = ms_row_altitude(py);
	vec3 sun[MS_SUN_GROUP];
	ms_row_suns(x0, h, sun);
	float r0 = P.BOTTOM_RADIUS_KM + h;
	// Only the scattering at x and beyond stays isotropic (Hillaire's
	// assumption); the first scattering's phases are per cell and sun.
	cell_phases(sun, lane);
	mat4x3 scattering_of = mat4x3(0.0), absorption_of = mat4x3(0.0);
	for (int i = 0; i < N_CONST; i++) {
		scattering_of[i] = P.c[i].scattering.rgb;
		absorption_of[i] = P.c[i].absorption.rgb;
	}
	for (int j = 0; j < MS_SUN_GROUP; j++) {
		sum_l2[j] = vec3(0.0);
		sum_ground[j] = vec3(0.0);
		sum_moment[j] = vec2(0.0);
		sum_second[j] = vec3(0.0);
	}
	sum_escape = vec3(0.0);
	sum_returned = vec3(0.0);
	sum_transfer = mat3(0.0);
	// do-while: lavapipe ends a for loop with one more pass, every lane
	// off, here a whole group of directions (lane < MS_LANES <= MS_MARCHED).
	int k = lane;
	do
		march_cells(k, h, r0, sun, ext_scaled, scattering_of, absorption_of);
	while ((k += MS_LANES * MS_TOGETHER) < MS_MARCHED);
	if (MS_LANES > 1) {
		reduce_cells(lane);
		if (lane != 0)
			return;
	}
	vec3 escape = sum_escape * MS_NORM;
	// The ground's first bounce G travels up: its next order is only what
	// the air scatters, never a reflection straight off the ground again,
	// so its higher orders take f - f_ground (f_ground the mean of the
	// returned transfer), not f: G (1 - f_ground) / (1 - f_ms) in all.
	vec3 ground_kept = 1.0 - sum_returned * MS_NORM;
	float escape_lum = max(dot(escape, MS_SHARE_LUM), 1e-6);
	for (int j = 0; j < MS_SUN_GROUP; j++) {
		if (x0 + j >= OUT_W)
			break;
		// 1 - f_ms is a sum of non-negative terms; the floor only keeps
		// 0 / 0 away (where the escape is 0, L2 is 0 too).
		vec3 psi = (sum_l2[j] + sum_ground[j] * ground_kept) * MS_NORM / max(escape, vec3(1e-6));
		if (MOMENT_CONST >= 0 && P.c[max(MOMENT_CONST, 0)].PHASE_G1 == 0.0)
			psi = (sum_l2[j] + sum_ground[j] * ground_kept) * MS_NORM /
			      max(escape - band2_transfer(j, h, psi, sun[j]), vec3(1e-6));
		// A: the ground's first bounce G (its mean over the sphere) as a
		// share of psi, which sky-view and aerial perspective scatter
		// through each constituent's phase (ground_excess()); its higher
		// orders stay isotropic. One share for the three channels,
		// weighted by luminance, since A is one value.
		float share = dot(sum_ground[j], MS_SHARE_LUM) * MS_NORM / max(dot(psi, MS_SHARE_LUM), 1e-30);
		STORE_TEXEL(MB, py * OUT_W + x0 + j, vec4(psi, clamp(share, 0.0, 1.0)));
		note_range(psi);
		if (MOMENT_CONST >= 0)
			store_shape(py * OUT_W + x0 + j, j, psi, sun[j], escape_lum,
				    light_visible(t_alt(h), sun[j].z, P.SUN_RADIUS_RAD));
	}
	flush_range(BINDING_MULTISCATTER - BINDING_TRANSMITTANCE);
}
