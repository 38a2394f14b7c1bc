/* oc_render.c — the CPU reference renderer (see oc_render.h for the model).
 *
 * Each pixel is independent, so rows are handed to threads through an atomic counter and the
 * image is the same for any thread count. Positions and distances along the ray are double;
 * the optics come from the shared C/GLSL headers in float, as on the GPU. */
#include "oc_render.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "atmosphere.h" /* ocg_atmo_extinction, ocg_atmo_*_scattering */
#include "brick.h"      /* ocg_code_decode, ocg_trilerp */
#include "oc_err.h"
#include "oc_log.h"
#include "oc_parallel.h"
#include "oc_planet.h"
#include "march.h"    /* the march: sources, segment update, ground, sun disc */
#include "optics.h"   /* phase functions, segment weights, octaves */
#include "sampling.h" /* ocg_jitter */
#include "shadow.h"   /* the cloud shadow volume's addressing and reconstruction */

/* Locating a leaf looks this far ahead along the ray so that a point on a shared face is found in
 * the node being entered, not the one being left (leaves are ≥ 6 m; doubles resolve 1e-9 m here). */
#define OC__LOCATE_EPS 1e-4
/* A shadow volume texel not walked yet (a NaN's bits: no walk returns it). */
#define OC__SHADOW_UNSET 0xFFFFFFFFu

typedef struct {
  int64_t idx;         /**< leaf index, -1 outside the root cube */
  const oc_node_t *n;  /**< NULL outside */
  const oc_brick_t *b; /**< brick payload for OC_NODE_BRICK */
  oc_dvec3 origin;
  double size;
} oc__leaf_t;

typedef struct {
  const oc_state_t *s;
  oc_render_desc_t d;
  oc_image_t *img;
  int have_atmo;
  ocg_atmosphere atm;
  ocg_vec3 sun_e;      /**< solar irradiance at the top of the atmosphere */
  ocg_cloud_model cm;  /**< albedo and multiple-scattering model */
  double ground_r;     /**< planet radius, or 0 without a planet */
  double air_top;      /**< atmosphere top radius */
  float air_sigma;     /**< thin air's σ (0: none; never with an atmosphere) */
  float sky;           /**< the uniform sky's radiance the thin air scatters (OC_BG_CONSTANT with ambient) */
  double thin_top;     /**< its shell's top above OC_PLANET_RADIUS */
  oc_render_stats_t *thread_stats;
  oc_shadow_frame_t shf; /**< the cloud shadow volume's place (shf.n[0] = 0: none) */
  ocg_shadow_grid sg;    /**< the same for shadow.h */
  _Atomic uint32_t *shadow; /**< its τ texels (float bits; OC__SHADOW_UNSET until walked), or NULL */
  ocg_shadow_grid gg;       /**< the ground map (shadow.h; nz = 1) */
  _Atomic uint32_t *ground; /**< its τ texels, as shadow's, or NULL */
} oc__ctx_t;

static int oc__bad(const char *field);

/* ---- State sampling ------------------------------------------------------------------------------ */

static void oc__leaf_locate(const oc_state_t *s, oc_dvec3 p, oc__leaf_t *lf) {
  oc_key_t k = oc_key_from_point(OC_KEY_MAX_LEVEL, p);
  lf->idx = k == OC_KEY_INVALID ? -1 : oc_state_find_leaf(s, k);
  if (lf->idx < 0) {
    lf->n = NULL;
    lf->b = NULL;
    return;
  }
  lf->n = &s->nodes[lf->idx];
  lf->b = lf->n->kind == OC_NODE_BRICK ? oc_state_find_brick(s, lf->n->brick_id) : NULL;
  oc_key_bounds(lf->n->key, &lf->origin, &lf->size);
}

/* One channel of a node at local position u ∈ [0,1]³: the shared reconstruction (brick.h). */
static float oc__leaf_channel(const oc__leaf_t *lf, int ch, ocg_vec3 u) {
  const oc_node_t *n = lf->n;
  if (!n || n->kind == OC_NODE_EMPTY) return 0.0f;
  if (n->kind == OC_NODE_UNIFORM || !lf->b) return n->range[ch].lo;
  float lo = n->range[ch].lo, hi = n->range[ch].hi;
  if (hi == 0.0f) return 0.0f;
  ocg_vec3 base = ocg_brick_base(u), f = ocg_brick_frac(u, base);
  ocg_uint b0 = ocg_brick_base_voxel(base);
  const uint16_t *c = lf->b->codes.code[ch];
  float v[8];
  for (ocg_uint q = 0; q < 8u; q++) v[q] = ocg_code_decode(c[b0 + ocg_brick_voxel(q & 1u, (q >> 1) & 1u, q >> 2)], lo, hi);
  return ocg_trilerp(ocg_v4(v[0], v[1], v[2], v[3]), ocg_v4(v[4], v[5], v[6], v[7]), f);
}

static ocg_vec3 oc__leaf_local(const oc__leaf_t *lf, oc_dvec3 p) {
  double inv = 1.0 / lf->size;
  return ocg_v3((float)((p.x - lf->origin.x) * inv), (float)((p.y - lf->origin.y) * inv),
                (float)((p.z - lf->origin.z) * inv));
}

float oc_render_sample_leaf(const oc_node_t *n, const oc_brick_t *b, oc_dvec3 origin, double size, int ch,
                            oc_dvec3 p) {
  if (!n) return 0.0f;
  const oc__leaf_t lf = {.n = n, .b = b, .origin = origin, .size = size};
  return oc__leaf_channel(&lf, ch, oc__leaf_local(&lf, p));
}

void oc_render_sample_state(const oc_state_t *s, oc_dvec3 p, float *sigma_t, float *tau) {
  oc__leaf_t lf;
  oc__leaf_locate(s, p, &lf);
  ocg_vec3 u = lf.n ? oc__leaf_local(&lf, p) : ocg_v3s(0.0f);
  *sigma_t = oc__leaf_channel(&lf, OC_CH_SIGMA, u);
  *tau = oc__leaf_channel(&lf, OC_CH_TAU, u);
}

/* ---- Geometry -------------------------------------------------------------------------------------- */

/* Ray–sphere (centre at the origin) entry/exit distances; false when missed. Written with the
 * stable quadratic form since |o| ≈ 6.4e6 m. */
static int oc__ray_sphere(oc_dvec3 o, oc_dvec3 d, double r, double *t0, double *t1) {
  double b = oc_ddot(o, d);
  double c = oc_ddot(o, o) - r * r;
  double disc = b * b - c;
  if (disc < 0.0) return 0;
  double sq = sqrt(disc);
  double q = b > 0.0 ? -(b + sq) : -(b - sq);
  double a0 = q, a1 = q != 0.0 ? c / q : 0.0;
  *t0 = a0 < a1 ? a0 : a1;
  *t1 = a0 < a1 ? a1 : a0;
  return 1;
}

int oc_render_air_shell(oc_dvec3 o, oc_dvec3 d, double top, double *t0, double *t1, double *t_ground) {
  double a0, a1, g0, g1;
  *t_ground = INFINITY;
  if (oc_ddot(o, o) < OC_PLANET_RADIUS * OC_PLANET_RADIUS) return 0;
  if (oc__ray_sphere(o, d, OC_PLANET_RADIUS, &g0, &g1) && g0 > 0.0) *t_ground = g0;
  if (!oc__ray_sphere(o, d, OC_PLANET_RADIUS + top, &a0, &a1) || !(a1 > 0.0)) return 0;
  *t0 = fmax(a0, 0.0);
  *t1 = fmin(a1, *t_ground);
  return *t1 > *t0;
}

/* e^{−σ ℓ_sun}: the thin air's transmittance toward the sun from p (ℓ_sun to the shell's top). */
static float oc__thin_air_sun(const oc__ctx_t *cx, oc_dvec3 p) {
  double a0, a1, g;
  if (!oc_render_air_shell(p, cx->s->sun_dir, cx->thin_top, &a0, &a1, &g)) return 1.0f;
  return (float)exp(-(double)cx->air_sigma * (a1 - a0));
}

/* Ray–AABB interval; false when missed. */
static int oc__ray_box(oc_dvec3 o, oc_dvec3 d, oc_dvec3 lo, oc_dvec3 hi, double *t0, double *t1) {
  double a = -INFINITY, b = INFINITY;
  const double oo[3] = {o.x, o.y, o.z}, dd[3] = {d.x, d.y, d.z}, l[3] = {lo.x, lo.y, lo.z}, h[3] = {hi.x, hi.y, hi.z};
  for (int i = 0; i < 3; i++) {
    if (dd[i] == 0.0) {
      if (oo[i] < l[i] || oo[i] > h[i]) return 0;
      continue;
    }
    double ta = (l[i] - oo[i]) / dd[i], tb = (h[i] - oo[i]) / dd[i];
    if (ta > tb) {
      double t = ta;
      ta = tb;
      tb = t;
    }
    if (ta > a) a = ta;
    if (tb < b) b = tb;
  }
  if (a > b) return 0;
  *t0 = a;
  *t1 = b;
  return 1;
}

/* Distance along the ray from p to the exit of the node's box. */
static double oc__node_exit(const oc__leaf_t *lf, oc_dvec3 p, oc_dvec3 d) {
  const double pp[3] = {p.x, p.y, p.z}, dd[3] = {d.x, d.y, d.z};
  const double o[3] = {lf->origin.x, lf->origin.y, lf->origin.z};
  double t = INFINITY;
  for (int i = 0; i < 3; i++) {
    if (dd[i] > 0.0) t = fmin(t, (o[i] + lf->size - pp[i]) / dd[i]);
    else if (dd[i] < 0.0) t = fmin(t, (o[i] - pp[i]) / dd[i]);
  }
  return t;
}

/* Clear-sky transmittance to the sun at radius r for sun cosine mu_s. Without an atmosphere, the
 * planet still casts its shadow (a hard edge) when there is a planet. */
static ocg_vec3 oc__sun_transmittance(const oc__ctx_t *cx, double r, double mu_s) {
  if (cx->have_atmo) return oc_atmo_sun_transmittance(cx->d.atmo, r, mu_s);
  if (cx->ground_r > 0.0 && r > cx->ground_r) {
    double horizon = -sqrt(fmax(0.0, 1.0 - (cx->ground_r / r) * (cx->ground_r / r)));
    if (mu_s < horizon) return ocg_v3s(0.0f);
  }
  return ocg_v3s(1.0f);
}

/* Longest air segment starting at p: at most air_len / air_steps, and short enough that the
 * altitude changes by at most a quarter of (altitude + 500 m) — the air thins exponentially
 * with a few-km scale height, so fixed steps leave rings where segment boundaries move from ray
 * to ray. Never below air_len / (16·air_steps), which bounds the cost of any ray. */
static double oc__air_step(const oc__ctx_t *cx, oc_dvec3 p, oc_dvec3 dir, double air_step) {
  double r = oc_dlen(p);
  double h = r - cx->atm.bottom_radius; /* only called with an atmosphere */
  return ocg_march_air_step((float)h, (float)(oc_ddot(p, dir) / r), (float)air_step);
}

/* ---- The cloud shadow volume (shaders/shadow.h) ------------------------------------------------------- */

int oc_render_shadow_frame(const oc_render_desc_t *desc, oc_dvec3 camera, double ground_r, oc_shadow_frame_t *f) {
  memset(f, 0, sizeof *f);
  double ext = desc->shadow_extent != 0.0 ? desc->shadow_extent : OC_RENDER_DEFAULT_SHADOW_EXTENT;
  double top = desc->shadow_top != 0.0 ? desc->shadow_top : OC_RENDER_DEFAULT_SHADOW_TOP;
  int cells = desc->shadow_cells ? desc->shadow_cells : OC_RENDER_DEFAULT_SHADOW_CELLS;
  int levels = desc->shadow_levels ? desc->shadow_levels : OC_RENDER_DEFAULT_SHADOW_LEVELS;
  if (!(ext >= 100.0 && ext <= 2e6)) return oc__bad("shadow_extent [100, 2e6] m");
  if (!(top >= 100.0 && top <= OCG_SHADOW_WALK_TOP)) return oc__bad("shadow_top [100, 30000] m");
  if (cells < 2 || cells > 4096) return oc__bad("shadow_cells [2, 4096]");
  if (levels < 2 || levels > 1024) return oc__bad("shadow_levels [2, 1024]");
  if ((double)cells * cells * levels > (double)(1 << 26)) return oc__bad("shadow_cells² × shadow_levels (at most 2^26)");
  int gcells = desc->shadow_ground_cells ? desc->shadow_ground_cells : OC_RENDER_DEFAULT_SHADOW_GROUND_CELLS;
  if (gcells != -1 && (gcells < OC_RENDER_SHADOW_GROUND_CELLS_MIN || gcells > OC_RENDER_SHADOW_GROUND_CELLS_MAX))
    return oc__bad("shadow_ground_cells [2, 4096] or -1");
  if ((desc->flags & OC_RF_NO_CLOUD_SHADOW) || !(ground_r > 0.0) || !(oc_dlen(camera) > 0.0)) return 0;
  oc_enu_t e = oc_enu_at(camera);
  double half = 0.5 * ext, drop = half * half / ground_r; /* the ground at a corner of the grid: (2·half²)/(2R) below */
  f->c0 = oc_dscale(e.up, ground_r);
  f->east = e.east;
  f->north = e.north;
  f->up = e.up;
  f->n[0] = f->n[1] = cells;
  f->n[2] = levels;
  f->lo[0] = f->lo[1] = -half;
  f->lo[2] = -drop;
  f->cell[0] = f->cell[1] = ext / (cells - 1);
  f->cell[2] = (top + drop) / (levels - 1);
  f->ground_n = gcells > 0 ? gcells : 0;
  f->ground_cell = gcells > 0 ? ext / (gcells - 1) : 0.0;
  return 0;
}

/* The τ toward the sun at p: the τ channel where the sun ray from p first enters a leaf with σt > 0. */
static float oc__shadow_walk(const oc__ctx_t *cx, oc_dvec3 p, float z0, float sun_z) {
  const oc_dvec3 sun = cx->s->sun_dir;
  oc__leaf_t lf;
  double t = 0.0;
  for (int i = 0; i < OCG_SHADOW_MAX_LEAVES; i++) {
    if (z0 + (float)t * sun_z > OCG_SHADOW_WALK_TOP && sun_z >= 0.0f) return 0.0f;
    oc_dvec3 q = oc_dmad(p, sun, t);
    oc__leaf_locate(cx->s, oc_dmad(p, sun, t + OC__LOCATE_EPS), &lf);
    if (!lf.n) return 0.0f;
    if (lf.n->range[OC_CH_SIGMA].hi > 0.0f) {
      ocg_vec3 u = ocg_max3(ocg_min3(oc__leaf_local(&lf, q), ocg_v3s(1.0f)), ocg_v3s(0.0f));
      return oc__leaf_channel(&lf, OC_CH_TAU, u);
    }
    t += fmax(oc__node_exit(&lf, q, sun), OC__LOCATE_EPS);
  }
  return 0.0f;
}

/* Texel (i, j, k) of the shadow volume (ground = 0) or (i, j) of the ground map (ground = 1, k = 0),
 * walked the first time it is asked for (lazily: a render pays only for the texels its rays touch).
 * Threads may walk the same texel at once; they store the same value, so the image does not depend on
 * the thread count. */
static float oc__shadow_texel(const oc__ctx_t *cx, int ground, int i, int j, int k) {
  const ocg_shadow_grid *g = ground ? &cx->gg : &cx->sg;
  _Atomic uint32_t *slot = &(ground ? cx->ground : cx->shadow)[ocg_shadow_index(*g, i, j, k)];
  uint32_t bits = atomic_load_explicit(slot, memory_order_relaxed);
  float v;
  if (bits != OC__SHADOW_UNSET) {
    memcpy(&v, &bits, sizeof v);
    return v;
  }
  const oc_shadow_frame_t *f = &cx->shf;
  ocg_vec3 q = ocg_shadow_texel(*g, i, j, k);
  if (ground) q.z = ocg_shadow_ground_z(q.x, q.y, (float)oc_dlen(f->c0));
  oc_dvec3 p = oc_dadd(oc_dadd(f->c0, oc_dscale(f->east, q.x)), oc_dadd(oc_dscale(f->north, q.y), oc_dscale(f->up, q.z)));
  v = oc__shadow_walk(cx, p, q.z, (float)oc_ddot(cx->s->sun_dir, f->up));
  memcpy(&bits, &v, sizeof bits);
  atomic_store_explicit(slot, bits, memory_order_relaxed);
  return v;
}

/* An array of n texels not walked yet, or NULL. */
static _Atomic uint32_t *oc__shadow_texels(size_t n) {
  _Atomic uint32_t *t = malloc(sizeof *t * n);
  for (size_t i = 0; t && i < n; i++) atomic_init(&t[i], OC__SHADOW_UNSET);
  return t;
}

static int oc__shadow_build(oc__ctx_t *cx) {
  const oc_shadow_frame_t *f = &cx->shf;
  cx->sg.lo = ocg_v3((float)f->lo[0], (float)f->lo[1], (float)f->lo[2]);
  cx->sg.cell = ocg_v3((float)f->cell[0], (float)f->cell[1], (float)f->cell[2]);
  cx->sg.nx = f->n[0];
  cx->sg.ny = f->n[1];
  cx->sg.nz = f->n[2];
  if (f->n[0] == 0) return 0;
  cx->shadow = oc__shadow_texels((size_t)f->n[0] * (size_t)f->n[1] * (size_t)f->n[2]);
  if (!cx->shadow) return OC_ENOMEM;
  if (f->ground_n == 0 || !(cx->ground_r > 0.0)) return 0; /* no ground (thin air over no planet): no map */
  float gc = (float)f->ground_cell;
  cx->gg = (ocg_shadow_grid){ocg_v3((float)f->lo[0], (float)f->lo[1], 0.0f), ocg_v3(gc, gc, 1.0f), f->ground_n, f->ground_n, 1};
  cx->ground = oc__shadow_texels((size_t)f->ground_n * (size_t)f->ground_n);
  return cx->ground ? 0 : OC_ENOMEM;
}

/* τ of the shadow volume at p (0 without one, or outside it), and its coordinates there to *c. */
static float oc__shadow_tau(const oc__ctx_t *cx, oc_dvec3 p, ocg_vec4 *c) {
  *c = ocg_v4(0.0f, 0.0f, 0.0f, 0.0f);
  if (!cx->shadow) return 0.0f;
  const oc_shadow_frame_t *f = &cx->shf;
  oc_dvec3 d = oc_dsub(p, f->c0);
  *c = ocg_shadow_coord(cx->sg, ocg_v3((float)oc_ddot(d, f->east), (float)oc_ddot(d, f->north), (float)oc_ddot(d, f->up)));
  if (c->w == 0.0f) return 0.0f;
  ocg_vec3 b = ocg_shadow_base(cx->sg, *c);
  int i = (int)b.x, j = (int)b.y, k = (int)b.z;
  float v[8];
  for (int q = 0; q < 8; q++) v[q] = oc__shadow_texel(cx, 0, i + (q & 1), j + ((q >> 1) & 1), k + (q >> 2));
  return ocg_shadow_tau(*c, b, ocg_v4(v[0], v[1], v[2], v[3]), ocg_v4(v[4], v[5], v[6], v[7]));
}

/* τ at the ground point p from the ground map, or from the volume without one; its coordinates to *c. */
static float oc__ground_map_tau(const oc__ctx_t *cx, oc_dvec3 p, ocg_vec4 *c) {
  if (!cx->ground) return oc__shadow_tau(cx, p, c);
  const oc_shadow_frame_t *f = &cx->shf;
  oc_dvec3 d = oc_dsub(p, f->c0);
  *c = ocg_shadow_ground_coord(cx->gg, ocg_v3((float)oc_ddot(d, f->east), (float)oc_ddot(d, f->north), 0.0f));
  if (c->w == 0.0f) return 0.0f;
  ocg_vec3 b = ocg_shadow_ground_base(cx->gg, *c);
  int i = (int)b.x, j = (int)b.y;
  float v[4];
  for (int q = 0; q < 4; q++) v[q] = oc__shadow_texel(cx, 1, i + (q & 1), j + (q >> 1), 0);
  return ocg_shadow_ground_tau(*c, b, ocg_v4(v[0], v[1], v[2], v[3]));
}

/* τ at p in leaf lf, which is not empty: its own, or where it holds no cloud and its samples are coarser
 * than the texels of the grid p reads (the ground map at a ground point, else the volume), the grid's
 * (shadow.h, ocg_shadow_over_leaf). */
static float oc__leaf_tau(const oc__ctx_t *cx, const oc__leaf_t *lf, oc_dvec3 p, int ground) {
  float own = oc__leaf_channel(lf, OC_CH_TAU, oc__leaf_local(lf, p));
  int map = ground && cx->ground;
  if (lf->n->range[OC_CH_SIGMA].hi > 0.0f || !cx->shadow || !ocg_shadow_finer(map ? cx->gg : cx->sg, (float)lf->size))
    return own;
  ocg_vec4 c;
  float vol = map ? oc__ground_map_tau(cx, p, &c) : oc__shadow_tau(cx, p, &c);
  return ocg_shadow_over_leaf(c, vol, own);
}

/* ---- One ray ----------------------------------------------------------------------------------------- */

static void oc__trace(const oc__ctx_t *cx, oc_dvec3 o, oc_dvec3 dir, float jitter, float out[4], oc_render_stats_t *st) {
  const oc_render_desc_t *d = &cx->d;
  const oc_dvec3 sun = cx->s->sun_dir;
  const float mu = (float)oc_ddot(dir, sun);
  const double S = OC_ROOT_HALF;
  ocg_march m = ocg_march_begin(mu);
  const float kap = ocg_ambient_far_kappa(cx->cm);

  /* The marched interval: the root cube (clouds) and, with air, the atmosphere sphere; cut by the ground. */
  double t0 = 0.0, t1 = 0.0, a0, a1;
  int in_cube = oc__ray_box(o, dir, oc_dv3(-S, -S, -S), oc_dv3(S, S, S), &a0, &a1);
  if (in_cube) {
    t0 = a0;
    t1 = a1;
  }
  double air_len = 0.0, air0 = 0.0, air1 = 0.0;
  if (cx->have_atmo && oc__ray_sphere(o, dir, cx->air_top, &a0, &a1) && a1 > 0.0) {
    air0 = a0 = fmax(a0, 0.0);
    air1 = a1;
    if (!in_cube) {
      t0 = a0;
      t1 = a1;
      in_cube = 1;
    }
  }
  t0 = fmax(t0, 0.0);
  int hit_ground = 0;
  if (cx->ground_r > 0.0) {
    if (oc_ddot(o, o) < cx->ground_r * cx->ground_r) { /* camera inside the planet: nothing visible */
      out[0] = out[1] = out[2] = 0.0f;
      out[3] = 0.0f;
      return;
    }
    if (oc__ray_sphere(o, dir, cx->ground_r, &a0, &a1) && a0 > 0.0) {
      hit_ground = 1;
      t1 = fmin(t1, a0);
    }
  }
  if (cx->have_atmo) air_len = fmin(air1, t1) - air0; /* the air actually crossed, up to the ground */
  double thin0 = INFINITY, thin1 = -INFINITY; /* thin air: its first shell crossing (shell ⊂ root cube) */
  if (cx->air_sigma > 0.0f && oc_render_air_shell(o, dir, cx->thin_top, &thin0, &thin1, &a0)) air_len = thin1 - thin0;
  double air_step = air_len > 0.0 ? air_len / d->air_steps : INFINITY;

  oc__leaf_t lf = {.idx = -2};
  int exited = 0, chord = 0; /* chord: past the early exit, measuring the run's depth only */
  double t = t0;
  while (in_cube && t < t1) {
    oc_dvec3 p = oc_dmad(o, dir, t);
    oc_dvec3 ploc = oc_dmad(o, dir, t + OC__LOCATE_EPS);
    if (lf.idx == -2 || !lf.n || ploc.x < lf.origin.x || ploc.y < lf.origin.y || ploc.z < lf.origin.z ||
        ploc.x >= lf.origin.x + lf.size || ploc.y >= lf.origin.y + lf.size || ploc.z >= lf.origin.z + lf.size) {
      oc__leaf_locate(cx->s, ploc, &lf);
      st->node_lookups++;
    }
    int cloudy = lf.n && lf.n->range[OC_CH_SIGMA].hi > 0.0f;
    double te = t1;
    if (lf.n) te = fmin(te, t + fmax(oc__node_exit(&lf, p, dir), OC__LOCATE_EPS));
    if (cloudy) te = fmin(te, ocg_march_step_end(t, d->step_factor * lf.size / 7.0 * (chord ? OCG_MS_CHORD_STEP : 1.0)));
    else if (lf.n) st->skipped_nodes++;
    if (cx->have_atmo) te = fmin(te, t + oc__air_step(cx, p, dir, air_step));
    else if (t < thin1) te = fmin(te, t < thin0 ? thin0 : fmin(thin1, t + air_step));
    double seg = te - t;
    oc_dvec3 pm = oc_dmad(o, dir, t + jitter * seg);
    int thin = t >= thin0 && t < thin1; /* the whole segment is in the thin air */

    float sig = 0.0f, tau = 0.0f;
    if (lf.n && lf.n->kind != OC_NODE_EMPTY) {
      if (cloudy) sig = oc__leaf_channel(&lf, OC_CH_SIGMA, oc__leaf_local(&lf, pm));
      if (!chord) tau = oc__leaf_tau(cx, &lf, pm, 0);
    } else if (!chord && (cx->have_atmo || thin)) {
      ocg_vec4 c;
      tau = oc__shadow_tau(cx, pm, &c); /* a node without τ: the shadow volume's */
    }
    if (chord) {
      st->samples++;
      t = te;
      if (!ocg_march_chord(&m, cx->cm, sig, kap, (float)seg)) break;
      continue;
    }
    double r = oc_dlen(pm);
    float mu_s = (float)(oc_ddot(pm, sun) / r);
    ocg_vec3 Esun = ocg_mul3(cx->sun_e, oc__sun_transmittance(cx, r, mu_s));
    if (thin) Esun = ocg_scale3(Esun, oc__thin_air_sun(cx, pm));
    ocg_vec3 sigma_t = ocg_v3s(sig);
    /* σs·S per metre: now; at the run's end (octaves, diffuse); the far side's ambient */
    ocg_vec3 J = ocg_v3s(0.0f), Jms = ocg_v3s(0.0f), Jmsd = ocg_v3s(0.0f), Jfar = ocg_v3s(0.0f);
    ocg_march_run(&m, cx->cm, sig, (float)seg); /* the run's gaps, before its depth is read */
    if (sig > 0.0f) {
      ocg_vec3 F = ocg_v3s(0.0f);
      if (cx->have_atmo && !(d->flags & OC_RF_NO_AMBIENT)) F = ocg_mul3(cx->sun_e, oc_atmo_sky_fluence(d->atmo, r, mu_s));
      else if (d->background == OC_BG_CONSTANT && !(d->flags & OC_RF_NO_AMBIENT))
        F = ocg_v3s(4.0f * OCG_PI * d->background_radiance); /* a uniform sky */
      J = ocg_cloud_source(cx->cm, sig, tau, m.tau_run, mu, Esun, F);
      Jms = ocg_cloud_source_ms(cx->cm, sig, tau, mu, Esun);
      Jmsd = ocg_cloud_source_msd(cx->cm, sig, tau, Esun);
      Jfar = ocg_cloud_source_far(cx->cm, sig, F);
      if (d->ms_oracle) { /* a candidate's multiply scattered light in place of the model's */
        float S = (float)d->ms_oracle(d->ms_oracle_ctx, pm, dir);
        J = ocg_add3(J, ocg_scale3(Esun, S * cx->cm.albedo * sig));
        Jms = Jmsd = ocg_v3s(0.0f);
      }
      ocg_ms_split(cx->cm, tau, mu, &J, &Jms, &Jmsd); /* after the oracle: it leaves nothing to split */
    }
    if (cx->have_atmo && r < cx->air_top) {
      float rf = (float)r;
      sigma_t = ocg_add3(sigma_t, ocg_atmo_extinction(cx->atm, rf));
      ocg_vec3 e_multi = ocg_mul3(cx->sun_e, oc_atmo_multiscatter(d->atmo, r, mu_s));
      J = ocg_add3(J, ocg_air_source(cx->atm, rf, mu, Esun, ocg_cloud_shadow(cx->cm, tau), e_multi));
    } else if (thin) {
      sigma_t = ocg_add3(sigma_t, ocg_v3s(cx->air_sigma));
      J = ocg_add3(J, ocg_thin_air_source(cx->air_sigma, Esun, ocg_cloud_shadow(cx->cm, tau), cx->sky));
    }
    ocg_march_segment(&m, sigma_t, sig, J, Jms, Jmsd, Jfar, kap, (float)seg);
    st->samples++;
    t = te;
    if (ocg_march_done(m, (float)d->exit_t)) {
      st->early_exits++;
      exited = 1;
      if (!ocg_march_wants_chord(m, cx->cm)) break;
      chord = 1;
    }
  }

  ocg_march_end_run(&m, cx->cm);
  if (!exited) {
    if (hit_ground) {
      oc_dvec3 pg = oc_dmad(o, dir, t1);
      double r = oc_dlen(pg);
      float mu_s = (float)(oc_ddot(pg, sun) / r);
      oc__leaf_t g;
      oc__leaf_locate(cx->s, pg, &g);
      ocg_vec4 c;
      float tg = g.n && g.n->kind != OC_NODE_EMPTY ? oc__leaf_tau(cx, &g, pg, 1) : oc__ground_map_tau(cx, pg, &c);
      float sg = ocg_cloud_shadow(cx->cm, tg);
      ocg_vec3 I = cx->have_atmo ? oc_atmo_sky_irradiance(d->atmo, r, mu_s) : ocg_v3s(0.0f);
      ocg_vec3 albedo = cx->have_atmo ? cx->atm.ground_albedo : ocg_v3s(0.1f);
      ocg_march_background(&m, ocg_ground_radiance(oc__sun_transmittance(cx, r, mu_s), mu_s, sg, I, albedo, cx->sun_e));
    } else if (d->background == OC_BG_CONSTANT) {
      ocg_march_background(&m, ocg_v3s(d->background_radiance));
    } else if (cx->have_atmo && !(d->flags & OC_RF_NO_SUN_DISC)) {
      ocg_march_background(&m, ocg_sun_disc(mu, cx->atm.sun_angular_radius, cx->sun_e));
    }
  }
  ocg_vec3 L = m.L;
  out[0] = L.x;
  out[1] = L.y;
  out[2] = L.z;
  out[3] = m.Tc;
  if (!isfinite(L.x) || !isfinite(L.y) || !isfinite(L.z)) st->nonfinite++;
}

/* ---- Threads ----------------------------------------------------------------------------------------- */

/* Row y of the image (an oc_parallel() item), counted in the stats of its thread. */
static void oc__row(void *arg, int y, int thread) {
  oc__ctx_t *cx = arg;
  oc_render_stats_t *st = &cx->thread_stats[thread];
  const oc_render_desc_t *d = &cx->d;
  for (int x = 0; x < d->width; x++) {
    oc_dvec3 dir = oc_camera_ray(&d->camera, d->width, d->height, x, y);
    float j = (d->flags & OC_RF_JITTER) ? ocg_jitter((ocg_uint)x, (ocg_uint)y, d->frame) : 0.5f;
    oc__trace(cx, d->camera.pos, dir, j, cx->img->px + 4 * ((size_t)y * (size_t)d->width + (size_t)x), st);
  }
}

static int oc__bad(const char *field) {
  oc_log_error("render: invalid %s", field);
  return OC_EINVAL;
}

int oc_render_state(const oc_state_t *s, const oc_render_desc_t *desc, oc_image_t *img, oc_render_stats_t *stats) {
  if (!s || !desc || !img) return OC_EINVAL;
  oc__ctx_t cx;
  memset(&cx, 0, sizeof cx);
  cx.s = s;
  cx.d = *desc;
  cx.img = img;
  oc_render_desc_t *d = &cx.d;
  if (d->width <= 0 || d->height <= 0 || img->w != d->width || img->h != d->height) return oc__bad("size");
  if (!(d->camera.vfov_deg > 0.0 && d->camera.vfov_deg < 180.0)) return oc__bad("camera fov");
  if (d->step_factor == 0.0) d->step_factor = OC_RENDER_DEFAULT_STEP_FACTOR;
  if (!(d->step_factor > 0.0 && d->step_factor <= 1e6)) return oc__bad("step_factor (0, 1e6]");
  if (d->air_steps == 0) d->air_steps = OC_RENDER_DEFAULT_AIR_STEPS;
  if (d->air_steps < 1 || d->air_steps > 1 << 20) return oc__bad("air_steps");
  if (d->exit_t == 0.0) d->exit_t = OC_RENDER_DEFAULT_EXIT_T;
  if (d->flags & OC_RF_NO_EARLY_EXIT) d->exit_t = -1.0;
  if (d->ms_octaves == 0) d->ms_octaves = OC_RENDER_DEFAULT_MS_OCTAVES;
  if (d->ms_octaves < 1 || d->ms_octaves > 16) return oc__bad("ms_octaves [1, 16]");
  if (d->ms_a == 0.0f) d->ms_a = OC_RENDER_DEFAULT_MS_A;
  if (d->ms_b == 0.0f) d->ms_b = OC_RENDER_DEFAULT_MS_B;
  if (d->ms_c == 0.0f) d->ms_c = OC_RENDER_DEFAULT_MS_C;
  if (!(d->ms_a > 0.0f && d->ms_a <= 1.0f)) return oc__bad("ms_a (0, 1]");
  if (!(d->ms_b > 0.0f && d->ms_b <= 1.0f)) return oc__bad("ms_b (0, 1]");
  if (!(d->ms_c > 0.0f && d->ms_c <= 1.0f)) return oc__bad("ms_c (0, 1]");
  if (d->ms_model != OC_MS_MODEL_DEPTH && d->ms_model != OC_MS_MODEL_OCTAVES) return oc__bad("ms_model");
  for (int i = 0; d->ms_fit && i < OC_RENDER_MS_FIT_N; i++) { /* the half-depth > 0, the rest ≥ 0; NaN fails */
    float v = d->ms_fit[i];
    if (!((i == 0 ? v > 0.0f : v >= 0.0f) && v < (i == 0 ? 1e6f : 1e3f))) return oc__bad("ms_fit");
  }
  if (d->albedo == 0.0f) d->albedo = 1.0f;
  if (d->albedo_zero) d->albedo = 0.0f;
  if (!(d->albedo >= 0.0f && d->albedo <= 1.0f)) return oc__bad("albedo [0, 1]");
  if (d->sun_irradiance == 0.0f) d->sun_irradiance = 1.0f;
  if (d->threads <= 0) d->threads = 1;
  if (d->threads > 256) return oc__bad("threads");

  cx.cm.albedo = d->albedo;
  cx.cm.ms_a = d->ms_a;
  cx.cm.ms_b = d->ms_b;
  cx.cm.ms_c = d->ms_c;
  cx.cm.ms_n = d->ms_octaves;
  cx.cm.legacy = d->ms_model == OC_MS_MODEL_OCTAVES;
  cx.cm.chord_half = d->ms_fit ? d->ms_fit[0] : OCG_MS_CHORD_HALF;
  cx.cm.albedo_power = d->ms_fit ? d->ms_fit[1] : OCG_MS_ALBEDO_POWER;
  cx.cm.ambient_k = d->ms_fit ? d->ms_fit[2] : OCG_AMBIENT_DEPTH_K;
  cx.cm.diffuse_b = d->ms_fit ? d->ms_fit[3] : OCG_MS_DIFFUSE_B;
  cx.cm.diffuse_a = d->ms_fit ? d->ms_fit[4] : OCG_MS_DIFFUSE_A;
  cx.cm.ms_forward = d->ms_fit ? d->ms_fit[5] : OCG_MS_FORWARD;
  cx.cm.sun_abs = d->ms_fit ? d->ms_fit[6] : OCG_MS_SUN_ABS;
  cx.cm.sun_share = d->ms_fit ? d->ms_fit[7] : OCG_MS_SUN_SHARE;
  cx.have_atmo = d->background != OC_BG_CONSTANT && !(d->flags & OC_RF_NO_ATMOSPHERE);
  if (cx.have_atmo && !d->atmo) return oc__bad("atmo (required with an atmosphere)");
  cx.air_top = OC_PLANET_RADIUS + OC_ATMOSPHERE_HEIGHT;
  cx.sun_e = ocg_v3s(d->sun_irradiance);
  if (cx.have_atmo) {
    cx.atm = *oc_atmo_params(d->atmo);
    cx.air_top = cx.atm.top_radius;
    cx.sun_e = ocg_scale3(cx.atm.solar_irradiance, d->sun_irradiance);
  }
  cx.ground_r = (d->background == OC_BG_CONSTANT || (d->flags & OC_RF_NO_PLANET)) ? 0.0
                : cx.have_atmo ? cx.atm.bottom_radius : OC_PLANET_RADIUS;
  if (!(d->air_sigma >= 0.0f && d->air_sigma <= (float)OC_RENDER_MAX_AIR_SIGMA)) return oc__bad("air_sigma [0, 1e-3] m⁻¹");
  if (d->air_top == 0.0) d->air_top = OC_RENDER_DEFAULT_AIR_TOP;
  if (!(d->air_top >= 100.0 && d->air_top <= OC_ATMOSPHERE_HEIGHT)) return oc__bad("air_top [100, 1e5] m");
  cx.air_sigma = cx.have_atmo ? 0.0f : d->air_sigma; /* the atmosphere has its own air */
  cx.thin_top = d->air_top;
  cx.sky = d->background == OC_BG_CONSTANT && !(d->flags & OC_RF_NO_AMBIENT) ? d->background_radiance : 0.0f;

  /* The shadow volume stands on the ground, or under thin air on the sphere of the planet radius. */
  double shadow_r = cx.ground_r > 0.0 ? cx.ground_r : cx.air_sigma > 0.0f ? OC_PLANET_RADIUS : 0.0;
  int rc = oc_render_shadow_frame(d, d->camera.pos, shadow_r, &cx.shf);
  if (rc < 0) return rc;
  rc = oc__shadow_build(&cx);
  cx.thread_stats = rc < 0 ? NULL : calloc((size_t)d->threads, sizeof *cx.thread_stats);
  if (!cx.thread_stats) {
    free((void *)cx.shadow);
    free((void *)cx.ground);
    return rc < 0 ? rc : OC_ENOMEM;
  }
  oc_parallel(d->height, d->threads, oc__row, &cx);

  oc_render_stats_t sum = {0};
  for (int i = 0; i < d->threads; i++) {
    sum.samples += cx.thread_stats[i].samples;
    sum.node_lookups += cx.thread_stats[i].node_lookups;
    sum.skipped_nodes += cx.thread_stats[i].skipped_nodes;
    sum.early_exits += cx.thread_stats[i].early_exits;
    sum.nonfinite += cx.thread_stats[i].nonfinite;
  }
  if (stats) *stats = sum;
  free(cx.thread_stats);
  free((void *)cx.shadow);
  free((void *)cx.ground);
  return 0;
}
