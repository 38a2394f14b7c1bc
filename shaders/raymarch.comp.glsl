/* raymarch.comp.glsl — one state raymarched per pixel: the integral of oc__trace in
 * common/oc_render.c, step for step, with the same shared march (shaders/march.h): this kernel only
 * finds the samples (octree, atlas, tables).
 *
 * Assembled after oc_port.h, sampling.h, optics.h, brick.h, shadow.h, atmosphere.h and march.h by
 * client/gl/gl_program.c;
 * the OCV_* constants come from client/gl/gl_render.c. GPU data layout: client/gl/README.md.
 *
 * Positions (design.md, Conventions): the shader never holds an absolute planet coordinate in float.
 * A point is its distance t along the ray from the camera, or the offset `rel` from the origin of the
 * camera's level-21 cell (u_cam_cell, integers; u_cam_frac, metres). Its level-21 cell is
 * u_cam_cell + floor(rel / cell) in integers, so the octree descent is exact, and a node's origin is
 * an integer cell difference times the cell size. Radii and sun cosines come from t and per-camera
 * constants the CPU computed in double (|o|², o·d split in two floats, o·sun), not from |o + t·d|. */

layout(local_size_x = 8, local_size_y = 8) in;

struct OcLeaf {
  vec4 range; /* σt lo, hi, τ lo, hi */
  uvec4 info; /* kind, atlas slot, level, 0 */
};
layout(std430, binding = 0) readonly buffer OcTree { uint oc_tree[]; };
layout(std430, binding = 1) readonly buffer OcLeaves { OcLeaf oc_leaf[]; };
layout(std430, binding = 2) writeonly buffer OcOut { vec4 oc_out[]; };
layout(std430, binding = 3) writeonly buffer OcDepth { float oc_depth[]; };
struct OcPrev {
  vec4 value; /* uniform previous σt, τ */
  uvec4 info; /* blends, uniform, pool entry (the first of 8 when fine), fine */
};
layout(std430, binding = 4) readonly buffer OcPrevs { OcPrev oc_prev[]; };
layout(binding = 5) uniform sampler3D u_prev_pool; /* RG32F: resampled previous bricks */
/* The cloud shadow volume (shaders/shadow.h): written by the shadow pass (OCV_SHADOW_PASS), read by the trace. */
layout(std430, binding = 6) buffer OcShadow { float oc_shadow[]; };
layout(std140, binding = 0) uniform OcAtmo { ocg_atmosphere u_atm; };

layout(binding = 0) uniform usampler3D u_atlas;
layout(binding = 1) uniform sampler2D u_tab_transmittance;
layout(binding = 2) uniform sampler2D u_tab_multiscatter;
layout(binding = 3) uniform sampler2D u_tab_irradiance;
layout(binding = 4) uniform sampler2D u_tab_fluence;

layout(location = 0) uniform ivec3 u_cam_cell;   /* camera's level-21 cell */
layout(location = 1) uniform vec3 u_cam_frac;    /* camera - that cell's origin, m */
layout(location = 2) uniform vec3 u_cam_hi;      /* camera (planet frame) = hi + lo: only for o·d */
layout(location = 3) uniform vec3 u_cam_lo;
layout(location = 4) uniform float u_cam_r2;     /* |o|², m² */
layout(location = 5) uniform vec3 u_fwd;
layout(location = 6) uniform vec3 u_right;
layout(location = 7) uniform vec3 u_up;
layout(location = 8) uniform vec2 u_tan;         /* tan(fov/2)·aspect, tan(fov/2) */
layout(location = 9) uniform ivec2 u_size;
layout(location = 10) uniform vec3 u_sun;
layout(location = 11) uniform float u_sun_o;     /* o·sun, m */
layout(location = 12) uniform float u_cell;      /* level-21 cell edge, m */
layout(location = 13) uniform float u_step_factor;
layout(location = 14) uniform int u_air_steps;
layout(location = 15) uniform float u_exit_t;    /* <= 0: no early exit */
layout(location = 16) uniform int u_ms_octaves;
layout(location = 17) uniform vec3 u_ms;         /* a, b, c */
layout(location = 18) uniform float u_albedo;
layout(location = 19) uniform vec3 u_sun_e;
layout(location = 20) uniform uint u_flags;
layout(location = 21) uniform uint u_frame;
layout(location = 22) uniform int u_have_atmo;
layout(location = 23) uniform float u_ground_r;  /* 0: no planet */
layout(location = 24) uniform int u_bg_constant;
layout(location = 25) uniform float u_bg_radiance;
layout(location = 26) uniform float u_c_ground;  /* |o|² - ground_r², m² */
layout(location = 27) uniform float u_c_top;     /* |o|² - air_top², m² */
layout(location = 28) uniform ivec3 u_atlas_bricks;
layout(location = 29) uniform int u_debug;       /* OC_DEBUG_* (common/oc_render.h) */
layout(location = 30) uniform int u_phase;       /* < 0: every pixel; else the one of each 4×4 block */
layout(location = 31) uniform int u_blend;       /* previous values present and t < 1 */
layout(location = 32) uniform float u_t;         /* blend parameter: mix(previous, newest, t) */
layout(location = 33) uniform ivec3 u_pool_bricks;
layout(location = 34) uniform int u_map_level;   /* octree map: 0 none, else its level (gl_state.c) */
layout(location = 35) uniform uint u_map_offset; /* its first word in oc_tree */
layout(location = 36) uniform int u_ms_model;    /* oc_ms_model_t: 0 fitted depth model, 1 legacy octaves */
layout(location = 37) uniform vec3 u_sh_lo;      /* the shadow volume (ocg_shadow_grid): texel 0, local m */
layout(location = 38) uniform vec3 u_sh_cell;    /* its spacing, m */
layout(location = 39) uniform ivec3 u_sh_n;      /* its texels per axis; x < 2: none */
layout(location = 40) uniform vec3 u_sh_cam;     /* the camera in its local frame, m */
layout(location = 41) uniform vec3 u_sh_e;       /* its local frame: east, north, up */
layout(location = 42) uniform vec3 u_sh_nn;
layout(location = 43) uniform vec3 u_sh_u;
layout(location = 45) uniform int u_sh_gn;       /* the ground map's texels a side (< 2: none), after the volume's */
layout(location = 46) uniform float u_sh_gcell;  /* their spacing, m (the volume's lo.xy is its corner) */

/* Shader variants (client/gl/gl_render.c): the renderer compiles one program per combination of the
 * features a frame uses, defining each of these as a constant, so the compiler drops the code of the
 * features that are off (no atmosphere: no air integral, no tables; a still state: no blend; no
 * debug view). Undefined, they read the uniforms: the generic program, kept for comparison. */
#ifndef OCV_ATMO
#define OCV_ATMO (u_have_atmo != 0)
#endif
#ifndef OCV_BLEND
#define OCV_BLEND (u_blend != 0)
#endif
#ifndef OCV_DEBUG
#define OCV_DEBUG (u_debug != 0)
#endif

/* Depth for reprojection: where the view transmittance first fell below ½, else the ground, else
 * far (a direction only). */
#define OCV_FAR 1e8

/* Debug colours are radiances: after exposure 10 and the ACES fit they come out saturated. */
vec3 ocv_level_color(uint level) {
  float h = float(level) / 21.0; /* blue (coarse) → green → red (level 21) */
  return 0.3 * clamp(vec3(2.0 * h - 0.5, 1.0 - abs(2.0 * h - 1.0), 1.5 - 2.0 * h), 0.0, 1.0);
}

/* Near an edge of the leaf: within 2 % of its size of two faces at once. */
bool ocv_on_edge(vec3 u) {
  vec3 e = min(u, 1.0 - u);
  int n = (e.x < 0.02 ? 1 : 0) + (e.y < 0.02 ? 1 : 0) + (e.z < 0.02 ? 1 : 0);
  return n >= 2;
}

#define OCV_LEAF_BIT 0x80000000u
#define OCV_NO_SLOT 0xFFFFFFFFu
#define OCV_CELLS21 (1 << 21)
#define OCV_BIG 1e30

struct OcvLeaf {
  int idx;      /* -1 outside the root cube */
  ivec3 lo;     /* level-21 cell of the node's origin */
  int cells;    /* edge in level-21 cells */
  vec3 origin;  /* relative to the camera cell's origin, m */
  float size;   /* m */
};

/* The leaf holding level-21 cell ic: descend the pointer octree one level per step. */
OcvLeaf ocv_locate_cell(ivec3 ic) {
  OcvLeaf lf;
  lf.idx = -1;
  lf.lo = ivec3(0);
  lf.cells = OCV_CELLS21;
  lf.origin = vec3(0.0);
  lf.size = 0.0;
  if (any(lessThan(ic, ivec3(0))) || any(greaterThanEqual(ic, ivec3(OCV_CELLS21)))) return lf;
  uint ref = oc_tree[0];
  int level = 0;
  if (u_map_level > 0) { /* the map resolves the first u_map_level steps in one read */
    uvec3 m = uvec3(ic) >> uint(21 - u_map_level);
    uint n = 1u << uint(u_map_level);
    ref = oc_tree[u_map_offset + m.x + n * (m.y + n * m.z)];
    level = (ref & OCV_LEAF_BIT) != 0u ? int(oc_leaf[ref & ~OCV_LEAF_BIT].info.z) : u_map_level;
  }
  while ((ref & OCV_LEAF_BIT) == 0u && level < 21) {
    level++;
    uvec3 b = (uvec3(ic) >> uint(21 - level)) & 1u;
    ref = oc_tree[1u + 8u * ref + (b.x | (b.y << 1) | (b.z << 2))];
  }
  lf.idx = int(ref & ~OCV_LEAF_BIT);
  lf.cells = 1 << (21 - level);
  lf.lo = (ic >> (21 - level)) << (21 - level);
  lf.origin = vec3(lf.lo - u_cam_cell) * u_cell;
  lf.size = float(lf.cells) * u_cell;
  return lf;
}

ivec3 ocv_cell_of(vec3 rel) { return u_cam_cell + ivec3(floor(rel / u_cell)); }

bool ocv_inside(OcvLeaf lf, ivec3 ic) {
  return all(greaterThanEqual(ic, lf.lo)) && all(lessThan(ic, lf.lo + ivec3(lf.cells)));
}

/* σt and τ of a leaf at local position u ∈ [0,1]³: brick.h's reconstruction, as oc__leaf_channel. */
vec2 ocv_leaf_sample(OcvLeaf lf, vec3 u) {
  if (lf.idx < 0) return vec2(0.0);
  OcLeaf L = oc_leaf[lf.idx];
  if (L.info.x == 0u) return vec2(0.0);
  if (L.info.x == 1u || L.info.y == OCV_NO_SLOT) return vec2(L.range.x, L.range.z);
  uint s = L.info.y;
  uint bx = uint(u_atlas_bricks.x), by = uint(u_atlas_bricks.y);
  vec3 base = ocg_brick_base(u), f = ocg_brick_frac(u, base);
  ivec3 at = ivec3(int(s % bx), int((s / bx) % by), int(s / (bx * by))) * 8 + ivec3(base);
  float vs[8], vt[8];
  for (int q = 0; q < 8; q++) {
    uvec2 c = texelFetch(u_atlas, at + ivec3(q & 1, (q >> 1) & 1, q >> 2), 0).rg;
    vs[q] = ocg_code_decode(c.x, L.range.x, L.range.y);
    vt[q] = ocg_code_decode(c.y, L.range.z, L.range.w);
  }
  float sig = L.range.y == 0.0 ? 0.0 : ocg_trilerp(vec4(vs[0], vs[1], vs[2], vs[3]), vec4(vs[4], vs[5], vs[6], vs[7]), f);
  float tau = L.range.w == 0.0 ? 0.0 : ocg_trilerp(vec4(vt[0], vt[1], vt[2], vt[3]), vec4(vt[4], vt[5], vt[6], vt[7]), f);
  return vec2(sig, tau);
}

vec3 ocv_local(OcvLeaf lf, vec3 rel) { return (rel - lf.origin) / lf.size; }

/* The leaf's previous σt, τ at u (client/interp.h): uniform, or the same reconstruction over the
 * pool's decoded samples: one entry over the whole leaf, or for a fine (merged) leaf the sub-brick
 * of u's octant c (entry + c, c_axis = u ≥ ½) at u' = 2u − c_axis, the children's resolution. */
vec2 ocv_prev_sample(int idx, vec3 u) {
  OcPrev P = oc_prev[idx];
  if (P.info.y != 0u) return P.value.xy;
  uint e = P.info.z, bx = uint(u_pool_bricks.x), by = uint(u_pool_bricks.y);
  if (P.info.w != 0u) {
    uvec3 c = uvec3(greaterThanEqual(u, vec3(0.5)));
    e += c.x | (c.y << 1) | (c.z << 2);
    u = clamp(2.0 * u - vec3(c), 0.0, 1.0);
  }
  vec3 base = ocg_brick_base(u), f = ocg_brick_frac(u, base);
  ivec3 at = ivec3(int(e % bx), int((e / bx) % by), int(e / (bx * by))) * 8 + ivec3(base);
  vec2 v[8];
  for (int q = 0; q < 8; q++) v[q] = texelFetch(u_prev_pool, at + ivec3(q & 1, (q >> 1) & 1, q >> 2), 0).rg;
  return vec2(ocg_trilerp(vec4(v[0].x, v[1].x, v[2].x, v[3].x), vec4(v[4].x, v[5].x, v[6].x, v[7].x), f),
              ocg_trilerp(vec4(v[0].y, v[1].y, v[2].y, v[3].y), vec4(v[4].y, v[5].y, v[6].y, v[7].y), f));
}

/* ---- Atmosphere tables: bilinear at texel centres, clamp to edge (oc_atmo_bake.c, oc__bilinear) ---- */

vec3 ocv_bilinear(sampler2D tab, vec2 uv) {
  ivec2 n = textureSize(tab, 0);
  float x = clamp(uv.x * float(n.x) - 0.5, -1.0, float(n.x));
  float y = clamp(uv.y * float(n.y) - 0.5, -1.0, float(n.y));
  int i0 = int(floor(x)), j0 = int(floor(y));
  float fx = x - float(i0), fy = y - float(j0);
  int i1 = clamp(i0 + 1, 0, n.x - 1), j1 = clamp(j0 + 1, 0, n.y - 1);
  i0 = clamp(i0, 0, n.x - 1);
  j0 = clamp(j0, 0, n.y - 1);
  vec3 a = texelFetch(tab, ivec2(i0, j0), 0).rgb, b = texelFetch(tab, ivec2(i1, j0), 0).rgb;
  vec3 c = texelFetch(tab, ivec2(i0, j1), 0).rgb, d = texelFetch(tab, ivec2(i1, j1), 0).rgb;
  return (1.0 - fy) * ((1.0 - fx) * a + fx * b) + fy * ((1.0 - fx) * c + fx * d);
}

/* oc__atmo_sun_transmittance */
vec3 ocv_atmo_sun_transmittance(float r, float mu_s) {
  if (!ocg_isfinite(r) || !ocg_isfinite(mu_s)) return vec3(0.0);
  mu_s = ocg_clamp_cos(mu_s);
  r = max(r, u_atm.bottom_radius);
  vec3 e = ocg_atmo_enter(u_atm, r, mu_s);
  if (e.z == 0.0) return vec3(1.0);
  float v = ocg_atmo_sun_visibility(u_atm, e.x, e.y);
  if (!(v > 0.0)) return vec3(0.0);
  return ocv_bilinear(u_tab_transmittance, ocg_atmo_transmittance_uv(u_atm, e.x, e.y)) * v;
}

vec3 ocv_atmo_rmus(sampler2D tab, float r, float mu_s) {
  if (!ocg_isfinite(r) || !ocg_isfinite(mu_s)) return vec3(0.0);
  ivec2 n = textureSize(tab, 0);
  return ocv_bilinear(tab, ocg_atmo_rmus_uv(u_atm, r, mu_s, float(n.x), float(n.y)));
}

/* oc__sun_transmittance: with air the tables; without, the planet's hard shadow. */
vec3 ocv_sun_transmittance(float r, float mu_s) {
  if (OCV_ATMO) return ocv_atmo_sun_transmittance(r, mu_s);
  if (u_ground_r > 0.0 && r > u_ground_r) {
    float g = u_ground_r / r;
    if (mu_s < -sqrt(max(0.0, 1.0 - g * g))) return vec3(0.0);
  }
  return vec3(1.0);
}

/* ---- Geometry -------------------------------------------------------------------------------------- */

/* Ray–sphere about the planet centre from b = o·d and c = |o|² - R² (stable quadratic, as oc__ray_sphere). */
bool ocv_ray_sphere(float b, float c, out float t0, out float t1) {
  t0 = 0.0;
  t1 = 0.0;
  float disc = b * b - c;
  if (disc < 0.0) return false;
  float sq = sqrt(disc);
  float q = b > 0.0 ? -(b + sq) : -(b - sq);
  float a0 = q, a1 = q != 0.0 ? c / q : 0.0;
  t0 = min(a0, a1);
  t1 = max(a0, a1);
  return true;
}

bool ocv_ray_box(vec3 o, vec3 d, vec3 lo, vec3 hi, out float t0, out float t1) {
  float a = -OCV_BIG, b = OCV_BIG;
  t0 = 0.0;
  t1 = 0.0;
  for (int i = 0; i < 3; i++) {
    if (d[i] == 0.0) {
      if (o[i] < lo[i] || o[i] > hi[i]) return false;
      continue;
    }
    float ta = (lo[i] - o[i]) / d[i], tb = (hi[i] - o[i]) / d[i];
    a = max(a, min(ta, tb));
    b = min(b, max(ta, tb));
  }
  if (a > b) return false;
  t0 = a;
  t1 = b;
  return true;
}

float ocv_node_exit(OcvLeaf lf, vec3 p, vec3 d) {
  float t = OCV_BIG;
  for (int i = 0; i < 3; i++) {
    if (d[i] > 0.0) t = min(t, (lf.origin[i] + lf.size - p[i]) / d[i]);
    else if (d[i] < 0.0) t = min(t, (lf.origin[i] - p[i]) / d[i]);
  }
  return t;
}

/* Radius at distance t along the ray: |o + t·d|² = |o|² + t(2 o·d + t). */
float ocv_radius(float b, float t) { return sqrt(max(u_cam_r2 + t * (2.0 * b + t), 0.0)); }

/* oc__air_step */
float ocv_air_step(float b, float t, float air_step) {
  float r = ocv_radius(b, t);
  return ocg_march_air_step(r - u_atm.bottom_radius, (b + t) / r, air_step);
}

/* ---- The cloud shadow volume (shaders/shadow.h; oc_render.c's oc__shadow_*) ------------------------------ */

ocg_shadow_grid ocv_shadow_grid() { return ocg_shadow_grid(u_sh_lo, u_sh_cell, u_sh_n.x, u_sh_n.y, u_sh_n.z); }

/* τ of the shadow volume at the local point q, and its coordinates there to c (oc__shadow_tau). */
float ocv_shadow_tau(vec3 q, out vec4 c) {
  ocg_shadow_grid g = ocv_shadow_grid();
  c = ocg_shadow_coord(g, q);
  if (c.w == 0.0) return 0.0;
  vec3 b = ocg_shadow_base(g, c);
  ivec3 i = ivec3(b);
  float v[8];
  for (int k = 0; k < 8; k++) v[k] = oc_shadow[ocg_shadow_index(g, i.x + (k & 1), i.y + ((k >> 1) & 1), i.z + (k >> 2))];
  return ocg_shadow_tau(c, b, vec4(v[0], v[1], v[2], v[3]), vec4(v[4], v[5], v[6], v[7]));
}

/* The ground map (shadow.h), its texels after the volume's in oc_shadow. */
ocg_shadow_grid ocv_ground_grid() { return ocg_shadow_grid(vec3(u_sh_lo.xy, 0.0), vec3(u_sh_gcell, u_sh_gcell, 1.0), u_sh_gn, u_sh_gn, 1); }
int ocv_ground_index(ocg_shadow_grid g, int i, int j) { return u_sh_n.x * u_sh_n.y * u_sh_n.z + ocg_shadow_index(g, i, j, 0); }

/* τ of the ground map at the local ground point q, or of the volume without a map (oc__ground_map_tau). */
float ocv_ground_map_tau(vec3 q, out vec4 c) {
  if (u_sh_gn < 2) return ocv_shadow_tau(q, c);
  ocg_shadow_grid g = ocv_ground_grid();
  c = ocg_shadow_ground_coord(g, q);
  if (c.w == 0.0) return 0.0;
  vec3 b = ocg_shadow_ground_base(g, c);
  ivec2 i = ivec2(b.xy);
  vec4 v = vec4(oc_shadow[ocv_ground_index(g, i.x, i.y)], oc_shadow[ocv_ground_index(g, i.x + 1, i.y)],
                oc_shadow[ocv_ground_index(g, i.x, i.y + 1)], oc_shadow[ocv_ground_index(g, i.x + 1, i.y + 1)]);
  return ocg_shadow_ground_tau(c, b, v);
}

/* τ at the local point q in a leaf that is not empty (own: its τ channel there): the grid's where the leaf
 * holds no cloud and its samples are coarser than the texels of the grid q reads, the ground map at a
 * ground point, else the volume (oc__leaf_tau, shadow.h). */
float ocv_leaf_tau(bool cloudy, float size, float own, vec3 q, bool ground) {
  bool map = ground && u_sh_gn >= 2;
  if (cloudy || ocg_shadow_finer(map ? ocv_ground_grid() : ocv_shadow_grid(), size) == 0) return own;
  vec4 c;
  float vol = map ? ocv_ground_map_tau(q, c) : ocv_shadow_tau(q, c);
  return ocg_shadow_over_leaf(c, vol, own);
}

/* τ at the ground point pg (camera-relative; q in the volume's frame): its leaf's, or the ground map's. */
float ocv_ground_tau(vec3 pg, vec3 q) {
  OcvLeaf g = ocv_locate_cell(ocv_cell_of(pg));
  vec4 c;
  if (g.idx < 0 || oc_leaf[g.idx].info.x == 0u) return ocv_ground_map_tau(q, c);
  return ocv_leaf_tau(oc_leaf[g.idx].range.y > 0.0, g.size, ocv_leaf_sample(g, ocv_local(g, pg)).y, q, true);
}

/* The τ channel where the sun ray from the local point q0 first enters a leaf with σt > 0 (oc__shadow_walk). */
float ocv_shadow_walk(vec3 q0) {
  vec3 rel = u_cam_frac + u_sh_e * (q0.x - u_sh_cam.x) + u_sh_nn * (q0.y - u_sh_cam.y) + u_sh_u * (q0.z - u_sh_cam.z);
  float sun_z = dot(u_sun, u_sh_u), t = 0.0;
  for (int i = 0; i < OCG_SHADOW_MAX_LEAVES; i++) {
    if (q0.z + t * sun_z > OCG_SHADOW_WALK_TOP && sun_z >= 0.0) return 0.0;
    vec3 p = rel + u_sun * t;
    float eps = max(OCV_LOCATE_EPS, length(p) * 1e-6);
    OcvLeaf lf = ocv_locate_cell(ocv_cell_of(p + u_sun * eps));
    if (lf.idx < 0) return 0.0;
    if (oc_leaf[lf.idx].range.y > 0.0) return ocv_leaf_sample(lf, clamp(ocv_local(lf, p), 0.0, 1.0)).y;
    t += max(ocv_node_exit(lf, p, u_sun), eps);
  }
  return 0.0;
}

/* ---- One ray (oc__trace) ------------------------------------------------------------------------------ */

/* The scene's cloud model (optics uniforms) with march.h's fitted constants. */
ocg_cloud_model ocv_cloud_model() {
  return ocg_cloud_model(u_albedo, u_ms.x, u_ms.y, u_ms.z, u_ms_octaves, u_ms_model, OCG_MS_CHORD_HALF, OCG_MS_ALBEDO_POWER,
                         OCG_AMBIENT_DEPTH_K, OCG_MS_DIFFUSE_B, OCG_MS_DIFFUSE_A, OCG_MS_FORWARD,
                         OCG_MS_SUN_ABS, OCG_MS_SUN_SHARE);
}

vec4 ocv_trace(vec3 dir, float jitter, out float depth) {
  depth = OCV_FAR;
  float mu = dot(dir, u_sun);
  float b = dot(u_cam_hi, dir) + dot(u_cam_lo, dir); /* o·d without the 0.5 m rounding of a float o */
  vec3 sh_dir = vec3(dot(dir, u_sh_e), dot(dir, u_sh_nn), dot(dir, u_sh_u)); /* dir in the shadow volume's frame */
  vec3 o = u_cam_frac;
  ocg_march m = ocg_march_begin(mu);
  ocg_cloud_model cm = ocv_cloud_model();
  float kap = ocg_ambient_far_kappa(cm);

  float t0 = 0.0, t1 = 0.0, a0, a1;
  vec3 box_lo = vec3(-u_cam_cell) * u_cell, box_hi = vec3(ivec3(OCV_CELLS21) - u_cam_cell) * u_cell;
  bool in_cube = ocv_ray_box(o, dir, box_lo, box_hi, a0, a1);
  if (in_cube) {
    t0 = a0;
    t1 = a1;
  }
  float air_len = 0.0, air0 = 0.0, air1 = 0.0;
  if (OCV_ATMO && ocv_ray_sphere(b, u_c_top, a0, a1) && a1 > 0.0) {
    a0 = max(a0, 0.0);
    air0 = a0;
    air1 = a1;
    if (!in_cube) {
      t0 = a0;
      t1 = a1;
      in_cube = true;
    }
  }
  t0 = max(t0, 0.0);
  bool hit_ground = false;
  if (u_ground_r > 0.0) {
    if (u_c_ground < 0.0) return vec4(0.0); /* camera inside the planet */
    if (ocv_ray_sphere(b, u_c_ground, a0, a1) && a0 > 0.0) {
      hit_ground = true;
      t1 = min(t1, a0);
    }
  }
  if (OCV_ATMO) air_len = min(air1, t1) - air0;
  float air_step = OCV_ATMO && air_len > 0.0 ? air_len / float(u_air_steps) : OCV_BIG;

  OcvLeaf lf;
  lf.idx = -1;
  lf.lo = ivec3(0);
  lf.cells = 0; /* matches no cell: the first step locates */
  lf.origin = vec3(0.0);
  lf.size = 0.0;
  bool exited = false, chord = false; /* chord: past the early exit, measuring the run's depth only */
  float t = t0;
  for (int it = 0; in_cube && t < t1 && it < OCV_MAX_STEPS; it++) {
    /* The look-ahead that puts a point on a shared face into the node being entered: CPU's 1e-4 m,
     * or more where a float t cannot resolve that (it must also guarantee progress). */
    float eps = max(OCV_LOCATE_EPS, t * 1e-6);
    vec3 p = o + dir * t;
    ivec3 ic = ocv_cell_of(o + dir * (t + eps));
    if (lf.cells == 0 || !ocv_inside(lf, ic)) lf = ocv_locate_cell(ic);
    bool has = lf.idx >= 0;
    vec4 range = has ? oc_leaf[lf.idx].range : vec4(0.0);
    uint kind = has ? oc_leaf[lf.idx].info.x : 0u;
    bool blend = OCV_BLEND && has && oc_prev[lf.idx].info.x != 0u;
    bool cloudy = has && (range.y > 0.0 || blend); /* a leaf empty now may have been cloudy */
    /* A merged leaf blending from its fine previous value (its children's resolution) is stepped
     * as its children were: octant by octant, at the children's step, so the picture at t = 0 is
     * the one they showed. */
    OcvLeaf box = lf;
    if (blend && oc_prev[lf.idx].info.w != 0u) {
      box.cells = lf.cells >> 1;
      box.lo = lf.lo + ivec3(greaterThanEqual(ic - lf.lo, ivec3(box.cells))) * box.cells;
      box.origin = vec3(box.lo - u_cam_cell) * u_cell;
      box.size = 0.5 * lf.size;
    }
    float te = t1;
    if (has) te = min(te, t + max(ocv_node_exit(box, p, dir), eps));
    if (cloudy) te = min(te, ocg_march_step_end(t, u_step_factor * box.size / 7.0 * (chord ? OCG_MS_CHORD_STEP : 1.0)));
    if (OCV_ATMO) te = min(te, t + ocv_air_step(b, t, air_step));
    te = max(te, t + eps);
    float seg = te - t;
    float tm = t + jitter * seg;

    float sig = 0.0, tau = 0.0;
    if (has && (kind != 0u || blend)) {
      vec3 u = ocv_local(lf, o + dir * tm);
      vec2 st = ocv_leaf_sample(lf, u);
      if (blend) st = mix(ocv_prev_sample(lf.idx, u), st, u_t);
      if (cloudy) sig = st.x;
      tau = chord ? st.y : ocv_leaf_tau(cloudy, lf.size, st.y, u_sh_cam + sh_dir * tm, false);
    } else if (!chord && OCV_ATMO) {
      vec4 c;
      tau = ocv_shadow_tau(u_sh_cam + sh_dir * tm, c); /* a node without τ: the shadow volume's */
    }
    if (chord) {
      t = te;
      if (!ocg_march_chord(m, cm, sig, kap, seg)) break;
      continue;
    }
    if (OCV_DEBUG && sig > 0.0) {
      if (u_debug == OCV_DEBUG_LOD) return vec4(ocv_level_color(oc_leaf[lf.idx].info.z), 0.0);
      if (u_debug == OCV_DEBUG_TAU) return vec4(vec3(0.3 * exp(-tau)), 0.0);
      if (u_debug == OCV_DEBUG_BOUNDS && ocv_on_edge(ocv_local(lf, p))) return vec4(0.3, 0.15, 0.0, 0.0);
    }
    float r = ocv_radius(b, tm);
    float mu_s = (u_sun_o + tm * mu) / r;
    vec3 Esun = u_sun_e * ocv_sun_transmittance(r, mu_s);
    vec3 sigma_t = vec3(sig);
    vec3 J = vec3(0.0), Jms = vec3(0.0), Jmsd = vec3(0.0), Jfar = vec3(0.0);
    ocg_march_run(m, cm, sig, seg); /* the run's gaps, before its depth is read */
    if (sig > 0.0) {
      vec3 F = vec3(0.0);
      if (OCV_ATMO && (u_flags & OCV_RF_NO_AMBIENT) == 0u) F = u_sun_e * ocv_atmo_rmus(u_tab_fluence, r, mu_s);
      else if (u_bg_constant != 0 && (u_flags & OCV_RF_NO_AMBIENT) == 0u) F = vec3(4.0 * OCG_PI * u_bg_radiance);
      J = ocg_cloud_source(cm, sig, tau, m.tau_run, mu, Esun, F);
      Jms = ocg_cloud_source_ms(cm, sig, tau, mu, Esun);
      Jmsd = ocg_cloud_source_msd(cm, sig, tau, Esun);
      ocg_ms_split(cm, tau, mu, J, Jms, Jmsd);
      Jfar = ocg_cloud_source_far(cm, sig, F);
    }
    if (OCV_ATMO && r < u_atm.top_radius) {
      sigma_t += ocg_atmo_extinction(u_atm, r);
      J += ocg_air_source(u_atm, r, mu, Esun, ocg_cloud_shadow(cm, tau), u_sun_e * ocv_atmo_rmus(u_tab_multiscatter, r, mu_s));
    }
    bool above = max(m.T.x, max(m.T.y, m.T.z)) >= 0.5;
    ocg_march_segment(m, sigma_t, sig, J, Jms, Jmsd, Jfar, kap, seg);
    if (above && max(m.T.x, max(m.T.y, m.T.z)) < 0.5 && depth == OCV_FAR) depth = tm;
    t = te;
    if (ocg_march_done(m, u_exit_t)) {
      exited = true;
      if (!ocg_march_wants_chord(m, cm)) break;
      chord = true;
    }
  }

  ocg_march_end_run(m, cm);
  if (!exited) {
    if (hit_ground) {
      if (depth == OCV_FAR) depth = t1;
      vec3 pg = o + dir * t1;
      float r = ocv_radius(b, t1);
      float mu_s = (u_sun_o + t1 * mu) / r;
      float sg = ocg_cloud_shadow(cm, ocv_ground_tau(pg, u_sh_cam + sh_dir * t1));
      vec3 I = OCV_ATMO ? ocv_atmo_rmus(u_tab_irradiance, r, mu_s) : vec3(0.0);
      vec3 albedo = OCV_ATMO ? u_atm.ground_albedo : vec3(0.1);
      ocg_march_background(m, ocg_ground_radiance(ocv_sun_transmittance(r, mu_s), mu_s, sg, I, albedo, u_sun_e));
    } else if (u_bg_constant != 0) {
      ocg_march_background(m, vec3(u_bg_radiance));
    } else if (OCV_ATMO && (u_flags & OCV_RF_NO_SUN_DISC) == 0u) {
      ocg_march_background(m, ocg_sun_disc(mu, u_atm.sun_angular_radius, u_sun_e));
    }
  }
  return vec4(m.L, m.Tc);
}

#ifdef OCV_SHADOW_PASS
layout(location = 44) uniform ivec2 u_sh_slice; /* (s, slices): rows of work groups s, s + slices, … (gl_render.c) */
/* The shadow pass: texel (x, y % n_y, y / n_y) of the shadow volume for the rows y < n_y·n_z; past them the
 * ground map's texels in memory order, n_x a row (so every row costs the same: gl_render.c's slices), each
 * on the ground under it (u_ground_r: the frame's radius). */
void main() {
  int gy = int(gl_WorkGroupID.y) * u_sh_slice.y + u_sh_slice.x;
  ivec2 g = ivec2(gl_GlobalInvocationID.x, gy * int(gl_WorkGroupSize.y) + int(gl_LocalInvocationID.y));
  int rows = u_sh_n.y * u_sh_n.z;
  if (g.y < rows) {
    if (g.x >= u_sh_n.x) return;
    ocg_shadow_grid sg = ocv_shadow_grid();
    int j = g.y % u_sh_n.y, k = g.y / u_sh_n.y;
    oc_shadow[ocg_shadow_index(sg, g.x, j, k)] = ocv_shadow_walk(ocg_shadow_texel(sg, g.x, j, k));
    return;
  }
  int at = (g.y - rows) * u_sh_n.x + g.x;
  if (g.x >= u_sh_n.x || at >= u_sh_gn * u_sh_gn) return;
  ocg_shadow_grid gg = ocv_ground_grid();
  vec3 q = ocg_shadow_texel(gg, at % u_sh_gn, at / u_sh_gn, 0);
  q.z = ocg_shadow_ground_z(q.x, q.y, u_ground_r);
  oc_shadow[ocv_ground_index(gg, at % u_sh_gn, at / u_sh_gn)] = ocv_shadow_walk(q);
}
#else
void main() {
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  if (px.x >= u_size.x || px.y >= u_size.y) return;
  float x = (2.0 * (float(px.x) + 0.5) / float(u_size.x) - 1.0) * u_tan.x;
  float y = (1.0 - 2.0 * (float(px.y) + 0.5) / float(u_size.y)) * u_tan.y;
  vec3 dir = normalize(u_fwd + u_right * x + u_up * y);
  if (u_phase >= 0 && ((px.x & 3) | ((px.y & 3) << 2)) != u_phase) return;
  float j = (u_flags & OCV_RF_JITTER) != 0u ? ocg_jitter(uint(px.x), uint(px.y), u_frame) : 0.5;
  float depth;
  oc_out[px.y * u_size.x + px.x] = ocv_trace(dir, j, depth);
  oc_depth[px.y * u_size.x + px.x] = depth;
}
#endif
