/* bench_oracle.c — the ceiling of a per-point multiply scattered term (bench_oracle.h). */
#include "bench_oracle.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "bench_mc.h"

typedef struct {
  int64_t ijk[3];
  double v[3]; /* toward the camera, from the first sample that asked for the point */
  double S;    /* in-scattered radiance per unit sun irradiance */
  int used;
} oct__opoint_t;

typedef struct {
  oct__opoint_t *t; /* open addressing by lattice index */
  size_t cap, n;
  double h; /* lattice spacing, m */
  int err; /* a record's failure: OC_ERANGE (over OCT_ORACLE_MAX_POINTS) or OC_ENOMEM; 0: none */
  const oct_oracle_opts_t *o;
  oct_mc_medium_t medium;
  oct_mc_params_t prm;
  double pl[OCT_ORACLE_MAX_LMAX + 1]; /* the phase function's Legendre moments */
  oct__opoint_t **list;               /* the used points, in table order */
} oct__oracle_t;

static uint64_t oct__ohash(const int64_t ijk[3]) {
  uint64_t x = (uint64_t)ijk[0] * 0x9E3779B97F4A7C15ull ^ (uint64_t)ijk[1] * 0xC2B2AE3D27D4EB4Full ^
               (uint64_t)ijk[2] * 0x165667B19E3779F9ull;
  return x ^ (x >> 29);
}

/* The point at ijk, or NULL; add: made where missing (the table is kept under half full). */
static oct__opoint_t *oct__opoint(oct__oracle_t *q, const int64_t ijk[3], int add) {
  for (size_t a = oct__ohash(ijk) & (q->cap - 1);; a = (a + 1) & (q->cap - 1)) {
    oct__opoint_t *e = &q->t[a];
    if (e->used && !memcmp(e->ijk, ijk, sizeof e->ijk)) return e;
    if (e->used) continue;
    if (!add) return NULL;
    memcpy(e->ijk, ijk, sizeof e->ijk);
    e->used = 1;
    q->n++;
    return e;
  }
}

/* Doubles the table (records run on one thread). @return 0 or OC_ENOMEM. */
static int oct__ogrow(oct__oracle_t *q) {
  oct__oracle_t old = *q;
  q->cap *= 2;
  q->n = 0;
  if (!(q->t = calloc(q->cap, sizeof *q->t))) {
    *q = old;
    return OC_ENOMEM;
  }
  for (size_t a = 0; a < old.cap; a++)
    if (old.t[a].used) *oct__opoint(q, old.t[a].ijk, 1) = old.t[a];
  free(old.t);
  return 0;
}

static void oct__ocell(const oct__oracle_t *q, oc_dvec3 p, int64_t b[3], double f[3]) {
  double x[3] = {p.x / q->h, p.y / q->h, p.z / q->h};
  for (int a = 0; a < 3; a++) b[a] = (int64_t)floor(x[a]), f[a] = x[a] - (double)b[a];
}

/* The first render: the 8 lattice points around every cloud sample, with the view they are seen from. */
static double oct__orecord(void *ctx, oc_dvec3 p, oc_dvec3 dir) {
  oct__oracle_t *q = ctx;
  int64_t b[3];
  double f[3];
  oct__ocell(q, p, b, f);
  for (int c = 0; c < 8 && !q->err; c++) {
    if (q->n >= OCT_ORACLE_MAX_POINTS) q->err = OC_ERANGE;
    else if (2 * (q->n + 1) > q->cap) q->err = oct__ogrow(q);
    if (q->err) break;
    int64_t ijk[3] = {b[0] + (c & 1), b[1] + (c >> 1 & 1), b[2] + (c >> 2)};
    oct__opoint_t *e = oct__opoint(q, ijk, 1);
    if (e->v[0] == 0.0 && e->v[1] == 0.0 && e->v[2] == 0.0) e->v[0] = -dir.x, e->v[1] = -dir.y, e->v[2] = -dir.z;
  }
  return 0.0;
}

/* The second render: trilinear between the 8 points around the sample. */
static double oct__olookup(void *ctx, oc_dvec3 p, oc_dvec3 dir) {
  (void)dir;
  oct__oracle_t *q = ctx;
  int64_t b[3];
  double f[3], s = 0.0;
  oct__ocell(q, p, b, f);
  for (int c = 0; c < 8; c++) {
    int64_t ijk[3] = {b[0] + (c & 1), b[1] + (c >> 1 & 1), b[2] + (c >> 2)};
    const oct__opoint_t *e = oct__opoint(q, ijk, 0);
    double w = (c & 1 ? f[0] : 1.0 - f[0]) * (c >> 1 & 1 ? f[1] : 1.0 - f[1]) * (c >> 2 ? f[2] : 1.0 - f[2]);
    if (e) s += w * e->S;
  }
  return s;
}

/* A uniformly distributed unit vector. */
static oc_dvec3 oct__ouniform(oct_mc_rng_t *r) {
  double z = 2.0 * oct_mc_uniform(r) - 1.0, phi = 6.283185307179586 * oct_mc_uniform(r);
  double s = sqrt(fmax(0.0, 1.0 - z * z));
  return (oc_dvec3){s * cos(phi), s * sin(phi), z};
}

/* The Legendre polynomials P_0 … P_lmax at mu (Bonnet's recurrence). */
static void oct__olegendre_at(double mu, int lmax, double P[OCT_ORACLE_MAX_LMAX + 1]) {
  P[0] = 1.0, P[1] = mu;
  for (int l = 2; l <= lmax; l++) P[l] = ((double)(2 * l - 1) * mu * P[l - 1] - (double)(l - 1) * P[l - 2]) / (double)l;
}

/* Σ_{l ≤ lmax} (2l + 1)·p_l·P_l(mu), the truncated phase function times 4π. */
static double oct__otruncated(const oct__oracle_t *q, double mu) {
  double P[OCT_ORACLE_MAX_LMAX + 1], s = 0.0;
  oct__olegendre_at(mu, q->o->lmax, P);
  for (int l = 0; l <= q->o->lmax; l++) s += (double)(2 * l + 1) * q->pl[l] * P[l];
  return s;
}

/* One lattice point's paths (an oc_parallel() item). A path traced from x along -w brings the light
 * that scattered somewhere and arrives at x travelling along w (bench_mc.h: out.sun, next-event
 * estimation at every collision; the unscattered sun is single scattering, the model's). */
static void oct__opoint_trace(void *ctx, int item, int thread) {
  (void)thread;
  oct__oracle_t *q = ctx;
  oct__opoint_t *e = q->list[item];
  oc_dvec3 x = {(double)e->ijk[0] * q->h, (double)e->ijk[1] * q->h, (double)e->ijk[2] * q->h};
  oc_dvec3 v = {e->v[0], e->v[1], e->v[2]};
  oct_mc_rng_t r;
  oct_mc_rng_seed(&r, 0x6f7261636c65ull, oct__ohash(e->ijk));
  oct_mc_stats_t st = {0};
  double sum = 0.0;
  for (long n = 0; n < q->o->paths; n++) {
    oc_dvec3 w = q->o->lmax < 0 ? oct_mc_phase_sample(&q->prm.phase, v, &r) : oct__ouniform(&r);
    oct_mc_path_t out;
    oct_mc_trace(&q->medium, &q->prm, x, (oc_dvec3){-w.x, -w.y, -w.z}, &r, &out, &st);
    sum += q->o->lmax < 0 ? out.sun : out.sun * oct__otruncated(q, oc_ddot(w, v));
  }
  e->S = fmax(sum / (double)q->o->paths, 0.0); /* a truncated phase function can go negative */
}

/* The phase function's Legendre moments p_l = ⟨P_l(μ)⟩, from 2²¹ exact samples (a fixed seed). */
static void oct__olegendre(oct__oracle_t *q) {
  enum { N = 1 << 21 };
  oct_mc_rng_t r;
  oct_mc_rng_seed(&r, 0x6c6567656e64ull, 0);
  double s[OCT_ORACLE_MAX_LMAX + 1] = {0}, P[OCT_ORACLE_MAX_LMAX + 1];
  for (int i = 0; i < N; i++) {
    oct__olegendre_at(oct_mc_phase_sample_mu(&q->prm.phase, &r), OCT_ORACLE_MAX_LMAX, P);
    for (int l = 0; l <= OCT_ORACLE_MAX_LMAX; l++) s[l] += P[l];
  }
  for (int l = 0; l <= OCT_ORACLE_MAX_LMAX; l++) q->pl[l] = s[l] / (double)N;
}

/* Collects the used points and traces them. @return 0 or OC_ENOMEM. */
static int oct__otrace_all(oct__oracle_t *q) {
  if (!(q->list = malloc((q->n ? q->n : 1) * sizeof *q->list))) return OC_ENOMEM;
  size_t k = 0;
  for (size_t a = 0; a < q->cap; a++)
    if (q->t[a].used) q->list[k++] = &q->t[a];
  oc_parallel((int)k, q->o->threads, oct__opoint_trace, q);
  return 0;
}

int oct_oracle_render(const oct_truth_case_t *c, const oc_state_t *st, const oc_render_desc_t *d, double length,
                      const oct_oracle_opts_t *o, oc_image_t *img, long *points) {
  if (!c || !st || !d || !o || !img || !(length > 0.0) || o->lmax < -1 || o->lmax > OCT_ORACLE_MAX_LMAX ||
      o->cells < 2 || o->cells > 256 || o->paths < 1 || o->threads < 1)
    return OC_EINVAL;
  oct__oracle_t q = {.cap = 1 << 16, .h = length / (double)o->cells, .o = o};
  q.prm = (oct_mc_params_t){.albedo = c->albedo, .phase = {OCT_MC_PHASE_HG_DRAINE, 0.0}, .sun = st->sun_dir,
                            .sun_irradiance = 1.0, .max_bounces = 100000000, .sun_lobe = 0.02};
  if (!(q.t = calloc(q.cap, sizeof *q.t))) return OC_ENOMEM;
  if (oct_mc_medium_state(&q.medium, st) < 0) {
    free(q.t);
    return OC_ENOMEM;
  }
  if (o->lmax >= 0) oct__olegendre(&q); /* the view mode samples the phase function itself */
  oc_render_desc_t d1 = *d;
  d1.ms_oracle = oct__orecord;
  d1.ms_oracle_ctx = &q;
  d1.threads = 1; /* the record is not shared between threads */
  int rc = oc_render_state(st, &d1, img, NULL);
  if (rc >= 0 && q.err) rc = q.err;
  if (rc >= 0) rc = oct__otrace_all(&q);
  if (rc >= 0) {
    d1 = *d;
    d1.ms_oracle = oct__olookup;
    d1.ms_oracle_ctx = &q;
    rc = oc_render_state(st, &d1, img, NULL);
  }
  if (points) *points = (long)q.n;
  oct_mc_medium_free(&q.medium);
  free(q.list);
  free(q.t);
  return rc < 0 ? rc : 0;
}
