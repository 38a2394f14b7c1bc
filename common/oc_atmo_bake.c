/* oc_atmo_bake.c — the atmosphere tables, computed in double from the shared header.
 *
 * This translation unit defines OCG_REAL_DOUBLE, so every formula of shaders/atmosphere.h (the
 * medium, the ray–sphere distances, the table mappings, the sun softening, the phase functions) runs
 * here in double: the tables come from the same code the shaders run, at higher precision. The
 * public float API is common/oc_atmo.c; docs/numerics.md ("Clear-sky atmosphere") describes the integrals.
 *
 * Quadrature.
 *   - Along a ray: the ray is split where it crosses "shells" (radii every two scale heights of the
 *     Mie and Rayleigh profiles, and the ozone tent's three kinks) and at its lowest point; each
 *     piece gets an n-point Gauss–Legendre rule. The optical depth from the ray's origin to every
 *     node comes from the rule's integration matrix (the integral of the interpolating polynomial),
 *     so transmittance along the ray costs no extra density evaluations.
 *   - Over directions: μ is split at the horizon μ_h (rays below it end on the ground) and each side
 *     is substituted μ = μ_h ± (1 ∓ μ_h)s², which removes the square-root behaviour of the path
 *     length at the horizon, then Gauss–Legendre in s; the azimuth about the zenith uses the
 *     midpoint rule on [0, π] (the integrand is even about the plane of the sun), which is the
 *     periodic trapezoid rule on the full circle. */
#define OCG_REAL_DOUBLE
#include "oc_atmo_internal.h"

#include <math.h>   /* cos, exp, sqrt */
#include <string.h> /* memset */

/*! Gauss–Legendre nodes per ray piece for the transmittance table's optical depths. */
#ifndef OC_ATMO_TAU_NODES
#define OC_ATMO_TAU_NODES 8
#endif
/*! Gauss–Legendre nodes per ray piece for the scattering tables (multiple scattering, irradiance,
 * fluence). */
#ifndef OC_ATMO_RAY_NODES
#define OC_ATMO_RAY_NODES 3
#endif
/*! Gauss–Legendre nodes in s per side of the horizon (μ = μ_h ± (1 ∓ μ_h)s²). */
#ifndef OC_ATMO_MU_NODES
#define OC_ATMO_MU_NODES 16
#endif
/*! Midpoint azimuths over [0, π] (twice as many over the full circle) for the irradiance and fluence
 * tables: they resolve the Cornette–Shanks forward peak. */
#ifndef OC_ATMO_PHI_NODES
#define OC_ATMO_PHI_NODES 12
#endif
/*! Midpoint azimuths over [0, π] for the multiple-scattering table (isotropic phase: smooth). */
#ifndef OC_ATMO_MS_PHI_NODES
#define OC_ATMO_MS_PHI_NODES 6
#endif

#define OC__PI 3.14159265358979323846
#define OC__RAY_MAX ((2 * OC__ATMO_MAX_SHELLS + 3) * OC_ATMO_RAY_NODES) /* nodes of a stored ray */
#if OC_ATMO_RAY_NODES > OC__ATMO_MAX_RULE || OC_ATMO_TAU_NODES > OC__ATMO_MAX_RULE || OC_ATMO_MU_NODES > OC__ATMO_MAX_RULE
#error "a quadrature rule is larger than OC__ATMO_MAX_RULE"
#endif

/* ---- Quadrature rules --------------------------------------------------------------------------------- */

/* Gauss–Legendre rule with n nodes on [0, 1] (Newton on P_n from Tricomi's initial guesses; a fixed
 * iteration count keeps it deterministic) and its integration matrix. */
static void oc__gl_rule(int n, oc__atmo_rule_t *q) {
  memset(q, 0, sizeof *q);
  q->n = n;
  for (int i = 0; i < n; i++) {
    double x = cos(OC__PI * (i + 0.75) / (n + 0.5)), p0 = 1.0, p1 = x, dp = 1.0;
    for (int it = 0; it < 8; it++) {
      p0 = 1.0;
      p1 = x;
      for (int k = 2; k <= n; k++) {
        double p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (x * p1 - p0) / (x * x - 1.0);
      x -= p1 / dp;
    }
    /* x_i descends with i; map to [0, 1] ascending. */
    q->x[i] = 0.5 * (1.0 - x);
    q->w[i] = 1.0 / ((1.0 - x * x) * dp * dp);
  }
  for (int i = 0; i < n; i++)
    for (int j = 0; j < n; j++) {
      /* ∫_0^{x_i} ℓ_j(y) dy with the same rule on [0, x_i] (exact: ℓ_j has degree n−1). */
      double s = 0.0;
      for (int k = 0; k < n; k++) {
        double y = q->x[i] * q->x[k], l = 1.0;
        for (int m = 0; m < n; m++)
          if (m != j) l *= (y - q->x[m]) / (q->x[j] - q->x[m]);
        s += q->w[k] * l;
      }
      q->S[i][j] = q->x[i] * s;
    }
}

void oc__atmo_prepare(struct oc_atmo_s *a) {
  const ocg_atmosphere *p = &a->p;
  double ht = (double)p->top_radius - (double)p->bottom_radius;
  double h[64];
  int n = 0;
  for (int k = 1; k <= 5; k++) h[n++] = 2.0 * k * p->mie_scale_height;
  for (int k = 1; k <= 12 && 2.0 * k * p->rayleigh_scale_height < ht; k++) h[n++] = 2.0 * k * p->rayleigh_scale_height;
  h[n++] = (double)p->ozone_center - p->ozone_half_width;
  h[n++] = p->ozone_center;
  h[n++] = (double)p->ozone_center + p->ozone_half_width;
  for (int i = 1; i < n; i++) /* insertion sort */
    for (int j = i; j > 0 && h[j - 1] > h[j]; j--) {
      double s = h[j];
      h[j] = h[j - 1];
      h[j - 1] = s;
    }
  a->nshell = 0;
  double last = 0.0;
  for (int i = 0; i < n && a->nshell < OC__ATMO_MAX_SHELLS; i++)
    if (h[i] > last + 1.0 && h[i] < ht - 1.0) {
      a->shell[a->nshell++] = (double)p->bottom_radius + h[i];
      last = h[i];
    }
  oc__gl_rule(OC_ATMO_TAU_NODES, &a->rule_tau);
  oc__gl_rule(OC_ATMO_RAY_NODES, &a->rule_ray);
  oc__gl_rule(OC_ATMO_MU_NODES, &a->rule_mu);
}

/* ---- Rays ------------------------------------------------------------------------------------------- */

typedef struct {
  int n;                       /* nodes */
  double t[OC__RAY_MAX];       /* distance from the origin, m */
  double w[OC__RAY_MAX];       /* quadrature weight, m */
  double r[OC__RAY_MAX];       /* radius */
  double T[OC__RAY_MAX][3];    /* transmittance origin → node */
  double sR[OC__RAY_MAX][3];   /* Rayleigh scattering, m⁻¹ */
  double sM[OC__RAY_MAX];      /* Mie scattering, m⁻¹ */
  double tau[3];               /* optical depth of the whole ray */
} oc__ray_t;

/* The ray (r, μ) over [0, d]: nodes with their transmittance from the origin (store) or only the
 * total optical depth (!store). */
static void oc__ray_build(const struct oc_atmo_s *a, const oc__atmo_rule_t *q, double r, double mu, double d,
                          oc__ray_t *ray, int store) {
  const ocg_atmosphere p = a->p;
  double bp[2 * OC__ATMO_MAX_SHELLS + 3];
  int nb = 0;
  double rmu = r * mu;
  bp[nb++] = 0.0;
  bp[nb++] = d;
  if (-rmu > 0.0 && -rmu < d) bp[nb++] = -rmu; /* lowest point */
  for (int k = 0; k < a->nshell; k++) {
    double R = a->shell[k];
    double disc = rmu * rmu - (r - R) * (r + R);
    if (disc <= 0.0) continue;
    double s = sqrt(disc);
    double t1 = -rmu - s, t2 = -rmu + s;
    if (t1 > 0.0 && t1 < d) bp[nb++] = t1;
    if (t2 > 0.0 && t2 < d) bp[nb++] = t2;
  }
  for (int i = 1; i < nb; i++)
    for (int j = i; j > 0 && bp[j - 1] > bp[j]; j--) {
      double s = bp[j];
      bp[j] = bp[j - 1];
      bp[j - 1] = s;
    }

  double tau[3] = {0.0, 0.0, 0.0};
  ray->n = 0;
  for (int k = 0; k + 1 < nb; k++) {
    double t0 = bp[k], len = bp[k + 1] - bp[k];
    if (!(len > 1e-6)) continue;
    double sig[OC__ATMO_MAX_RULE][3];
    for (int i = 0; i < q->n; i++) {
      double t = t0 + len * q->x[i];
      double rt = ocg_atmo_radius_at(r, mu, t);
      ocg_vec3 e = ocg_atmo_extinction(p, rt);
      sig[i][0] = e.x;
      sig[i][1] = e.y;
      sig[i][2] = e.z;
      if (store) {
        int m = ray->n + i;
        ocg_vec3 sr = ocg_atmo_rayleigh_scattering(p, rt);
        ray->t[m] = t;
        ray->w[m] = len * q->w[i];
        ray->r[m] = rt;
        ray->sR[m][0] = sr.x;
        ray->sR[m][1] = sr.y;
        ray->sR[m][2] = sr.z;
        ray->sM[m] = ocg_atmo_mie_scattering(p, rt);
      }
    }
    for (int c = 0; c < 3; c++) {
      if (store)
        for (int i = 0; i < q->n; i++) {
          double s = 0.0;
          for (int j = 0; j < q->n; j++) s += q->S[i][j] * sig[j][c];
          ray->T[ray->n + i][c] = exp(-(tau[c] + len * s));
        }
      double s = 0.0;
      for (int j = 0; j < q->n; j++) s += q->w[j] * sig[j][c];
      tau[c] += len * s;
    }
    if (store) ray->n += q->n;
  }
  for (int c = 0; c < 3; c++) ray->tau[c] = tau[c];
}

/* ---- Look-ups (bilinear at texel centres, clamp to edge: GL_LINEAR + GL_CLAMP_TO_EDGE) ------------- */

static void oc__bilinear(const oc__atmo_tab_t *tb, double u, double v, double out[3]) {
  double x = u * tb->w - 0.5, y = v * tb->h - 0.5;
  /* Clamp far outside first (no integer overflow); inside [-1, w] clamping to edge is unchanged. */
  x = x < -1.0 ? -1.0 : x > tb->w ? tb->w : x;
  y = y < -1.0 ? -1.0 : y > tb->h ? tb->h : y;
  int i0 = (int)(x + 1.0) - 1, j0 = (int)(y + 1.0) - 1; /* floor: x, y ≥ -1 here */
  double fx = x - i0, fy = y - j0;
  int i1 = i0 + 1, j1 = j0 + 1;
  i0 = i0 < 0 ? 0 : i0 > tb->w - 1 ? tb->w - 1 : i0;
  i1 = i1 < 0 ? 0 : i1 > tb->w - 1 ? tb->w - 1 : i1;
  j0 = j0 < 0 ? 0 : j0 > tb->h - 1 ? tb->h - 1 : j0;
  j1 = j1 < 0 ? 0 : j1 > tb->h - 1 ? tb->h - 1 : j1;
  const float *a = tb->rgba + 4 * ((size_t)j0 * tb->w + i0), *b = tb->rgba + 4 * ((size_t)j0 * tb->w + i1);
  const float *c = tb->rgba + 4 * ((size_t)j1 * tb->w + i0), *d = tb->rgba + 4 * ((size_t)j1 * tb->w + i1);
  for (int k = 0; k < 3; k++)
    out[k] = (1.0 - fy) * ((1.0 - fx) * a[k] + fx * b[k]) + fy * ((1.0 - fx) * c[k] + fx * d[k]);
}

/* Transmittance to the sun from inside the shell (b ≤ r ≤ t), softened over the sun disc. */
static void oc__sun_T(const struct oc_atmo_s *a, double r, double mu_s, double out[3]) {
  double v = ocg_atmo_sun_visibility(a->p, r, mu_s);
  if (!(v > 0.0)) {
    out[0] = out[1] = out[2] = 0.0;
    return;
  }
  ocg_vec2 uv = ocg_atmo_transmittance_uv(a->p, r, mu_s);
  oc__bilinear(&a->tab[0], uv.x, uv.y, out);
  for (int k = 0; k < 3; k++) out[k] *= v;
}

static void oc__rmus(const struct oc_atmo_s *a, int which, double r, double mu_s, double out[3]) {
  const oc__atmo_tab_t *tb = &a->tab[which];
  ocg_vec2 uv = ocg_atmo_rmus_uv(a->p, r, mu_s, tb->w, tb->h);
  oc__bilinear(tb, uv.x, uv.y, out);
}

static int oc__finite2(double a, double b) { return isfinite(a) && isfinite(b); }

/* Where the ray from radius r (raised to the ground) at cosine mu (clamped) enters the atmosphere:
 * @return 1 and *e, or 0 with out the answer (1: it never enters; 0: r or mu not finite). */
static int oc__enter(const struct oc_atmo_s *a, double r, double mu, double out[3], ocg_vec3 *e) {
  out[0] = out[1] = out[2] = 0.0;
  if (!oc__finite2(r, mu)) return 0;
  mu = ocg_clamp_cos(mu);
  r = fmax(r, a->p.bottom_radius);
  *e = ocg_atmo_enter(a->p, r, mu);
  if (e->z != 0.0) return 1;
  out[0] = out[1] = out[2] = 1.0;
  return 0;
}

void oc__atmo_transmittance(const struct oc_atmo_s *a, double r, double mu, double out[3]) {
  ocg_vec3 e;
  if (!oc__enter(a, r, mu, out, &e) || ocg_atmo_ray_hits_ground(a->p, e.x, e.y)) return;
  ocg_vec2 uv = ocg_atmo_transmittance_uv(a->p, e.x, e.y);
  oc__bilinear(&a->tab[0], uv.x, uv.y, out);
}

void oc__atmo_sun_transmittance(const struct oc_atmo_s *a, double r, double mu_s, double out[3]) {
  ocg_vec3 e;
  if (oc__enter(a, r, mu_s, out, &e)) oc__sun_T(a, e.x, e.y, out);
}

void oc__atmo_rmus_lookup(const struct oc_atmo_s *a, int which, double r, double mu_s, double out[3]) {
  out[0] = out[1] = out[2] = 0.0;
  if (!oc__finite2(r, mu_s) || which < 1 || which >= OC__ATMO_NTABLES) return;
  oc__rmus(a, which, r, mu_s, out);
}

/* ---- Tables ---------------------------------------------------------------------------------------- */

#define OC__MAX_COLS 64 /* the widest (r, μs) table */
#if OC_ATMO_PHI_NODES > OC__ATMO_MAX_PHI || OC_ATMO_MS_PHI_NODES > OC__ATMO_MAX_PHI
#error "more azimuths than OC__ATMO_MAX_PHI"
#endif

static void oc__store(float *texel, const double v[3]) {
  texel[0] = (float)v[0];
  texel[1] = (float)v[1];
  texel[2] = (float)v[2];
  texel[3] = 1.0f;
}

/* Transmittance to the top of the atmosphere, T(r, μ) = exp(-∫_0^{d_t} σ_t(r_s) ds). */
static void oc__eval_transmittance(const struct oc_atmo_s *a, double r, double mu, double out[3]) {
  oc__ray_t ray;
  oc__ray_build(a, &a->rule_tau, r, mu, ocg_atmo_dist_top(a->p, r, mu), &ray, 0);
  for (int c = 0; c < 3; c++) out[c] = exp(-ray.tau[c]);
}

/* Every texel centre's ray (none meets the ground: x_μ = 1 is the horizon itself). */
static void oc__bake_transmittance(struct oc_atmo_s *a, int j) {
  oc__atmo_tab_t *tb = &a->tab[0];
  for (int i = 0; i < tb->w; i++) {
    ocg_vec2 rm = ocg_atmo_transmittance_rmu(a->p, ocg_v2((i + 0.5) / tb->w, (j + 0.5) / tb->h));
    double T[3];
    oc__eval_transmittance(a, rm.x, rm.y, T);
    oc__store(tb->rgba + 4 * ((size_t)j * tb->w + i), T);
  }
}

/* The zenith-cosine nodes of one side of the horizon: side 0 above (no ground), 1 below. */
static void oc__mu_node(const oc__atmo_rule_t *q, int k, int side, double mu_h, double *mu, double *wmu) {
  double s = q->x[k];
  if (side == 0) {
    *mu = mu_h + (1.0 - mu_h) * s * s;
    *wmu = 2.0 * (1.0 - mu_h) * s * q->w[k];
  } else {
    *mu = mu_h - (1.0 + mu_h) * s * s;
    *wmu = 2.0 * (1.0 + mu_h) * s * q->w[k];
  }
}

/* The ray of a direction node: length to the ground (side 1) or the top (side 0). */
static double oc__side_dist(const ocg_atmosphere p, double r, double mu, int side) {
  return side ? ocg_atmo_dist_bottom(p, r, mu) : ocg_atmo_dist_top(p, r, mu);
}

/* Cosine between a direction (μ, azimuth φ about the zenith) and the sun (μs, azimuth 0). */
static double oc__nu(double mu, double mu_s, int m, int nphi) {
  double sin_v = sqrt(fmax(0.0, 1.0 - mu * mu)), sin_s = sqrt(fmax(0.0, 1.0 - mu_s * mu_s));
  return mu * mu_s + sin_v * sin_s * cos(OC__PI * (m + 0.5) / nphi);
}

/* The ground as seen from radius r: its radius, the horizon's zenith cosine and its Lambertian BRDF a/π. */
typedef struct {
  double b, mu_h, brdf[3];
} oc__ground_t;

static oc__ground_t oc__ground(const ocg_atmosphere p, double r) {
  ocg_vec3 alb = ocg_atmo_f3(p.ground_albedo);
  return (oc__ground_t){p.bottom_radius, ocg_atmo_horizon_mu(p, r), {alb.x / OC__PI, alb.y / OC__PI, alb.z / OC__PI}};
}

/* ---- Per-node rows --------------------------------------------------------------------------------
 * The scattering tables look the transmittance and Ψ_ms tables up at every ray node for many sun
 * directions. The node's radius fixes the tables' v, so each node first interpolates the two rows
 * (the v half of GL's bilinear filter) and every direction then does the u half from L1: the same
 * bilinear value up to rounding, without a cache miss per look-up. */

typedef struct {
  double T[OCG_ATMO_TRANSMITTANCE_W][3]; /* transmittance table, rows interpolated at r */
  double P[OC__MAX_COLS][3];             /* multiscatter table, rows interpolated at r */
} oc__rows_t;

/* Row j0/j1 interpolation of a table at v (clamp to edge), into row[w][3]. */
static void oc__rows_at(const oc__atmo_tab_t *tb, double v, double (*row)[3]) {
  double y = v * tb->h - 0.5;
  y = y < -1.0 ? -1.0 : y > tb->h ? tb->h : y;
  int j0 = (int)(y + 1.0) - 1;
  double fy = y - j0;
  int j1 = j0 + 1;
  j0 = j0 < 0 ? 0 : j0 > tb->h - 1 ? tb->h - 1 : j0;
  j1 = j1 < 0 ? 0 : j1 > tb->h - 1 ? tb->h - 1 : j1;
  const float *a = tb->rgba + 4 * (size_t)j0 * tb->w, *c = tb->rgba + 4 * (size_t)j1 * tb->w;
  for (int i = 0; i < tb->w; i++)
    for (int k = 0; k < 3; k++) row[i][k] = (1.0 - fy) * a[4 * i + k] + fy * c[4 * i + k];
}

/* The u half of the bilinear filter on an interpolated row of w texels. */
static inline void oc__lerp_u(const double (*row)[3], int w, double u, double out[3]) {
  double x = u * w - 0.5;
  x = x < -1.0 ? -1.0 : x > w ? w : x;
  int i0 = (int)(x + 1.0) - 1;
  double fx = x - i0;
  int i1 = i0 + 1;
  i0 = i0 < 0 ? 0 : i0 > w - 1 ? w - 1 : i0;
  i1 = i1 < 0 ? 0 : i1 > w - 1 ? w - 1 : i1;
  for (int k = 0; k < 3; k++) out[k] = (1.0 - fx) * row[i0][k] + fx * row[i1][k];
}

static void oc__rows_prepare(const struct oc_atmo_s *a, double r, int want_psi, oc__rows_t *rows) {
  oc__rows_at(&a->tab[0], ocg_atmo_transmittance_uv(a->p, r, 1.0).y, rows->T);
  if (want_psi) oc__rows_at(&a->tab[1], ocg_atmo_multiscatter_uv(a->p, r, 0.0).y, rows->P);
}

/* oc__sun_T at the node's radius r from its rows. */
static inline void oc__sun_T_rows(const struct oc_atmo_s *a, const oc__rows_t *rows, double r, double mu_s, double out[3]) {
  double v = ocg_atmo_sun_visibility(a->p, r, mu_s);
  if (!(v > 0.0)) {
    out[0] = out[1] = out[2] = 0.0;
    return;
  }
  oc__lerp_u(rows->T, OCG_ATMO_TRANSMITTANCE_W, ocg_atmo_transmittance_uv(a->p, r, mu_s).x, out);
  for (int k = 0; k < 3; k++) out[k] *= v;
}

/* Ψ_ms at the node's radius from its rows. */
static inline void oc__psi_rows(const struct oc_atmo_s *a, const oc__rows_t *rows, double r, double mu_s, double out[3]) {
  oc__lerp_u(rows->P, OCG_ATMO_MULTISCATTER_W, ocg_atmo_multiscatter_uv(a->p, r, mu_s).x, out);
}

/* The directions of one zenith-cosine node: azimuth m of column i has cosine ν to the sun. */
typedef struct {
  double nu[OC__MAX_COLS][OC__ATMO_MAX_PHI];
  double L[OC__MAX_COLS][OC__ATMO_MAX_PHI][3]; /* accumulated radiance */
} oc__dirs_t;

/* Zenith-cosine node k of one side of the horizon seen from radius r: its cosine *mu and weight *wmu, the
 * ray along it (to the ground or the top) and, in dirs->nu, each azimuth's cosine to the n suns.
 * @return the ray's length. */
static double oc__dir_node(const struct oc_atmo_s *a, double r, int side, double mu_h, int k, int n,
                           const double *mu_s, int nphi, double *mu, double *wmu, oc__ray_t *ray, oc__dirs_t *dirs) {
  oc__mu_node(&a->rule_mu, k, side, mu_h, mu, wmu);
  double d = oc__side_dist(a->p, r, *mu, side);
  oc__ray_build(a, &a->rule_ray, r, *mu, d, ray, 1);
  for (int i = 0; i < n; i++)
    for (int m = 0; m < nphi; m++) dirs->nu[i][m] = oc__nu(*mu, mu_s[i], m, nphi);
  return d;
}

/* Hillaire 2020's multiple-scattering transfer Ψ_ms(r, μs), per unit solar irradiance:
 *   L2 = (1/4π) ∫_4π L'(ω) dω,   f_ms = (1/4π) ∫_4π f(ω) dω,   Ψ_ms = L2 / (1 − f_ms),
 *   L'(ω) = ∫_0^d T(0,s) σ_s(s) (1/4π) T_sun(s) ds + [ground] T(0,d) (a/π) T_sun(g) max(μ_s,g, 0),
 *   f(ω)  = ∫_0^d T(0,s) σ_s(s) ds,
 * with σ_s = β_R + β^s_M, the isotropic phase 1/4π for both orders (Hillaire's choice), and T_sun the
 * softened transmittance to the sun (the transmittance table, as at run time). n values of μs. */
static void oc__eval_multiscatter(const struct oc_atmo_s *a, double r, int n, const double *mu_s, double (*out)[3]) {
  const int nphi = OC_ATMO_MS_PHI_NODES;
  const oc__ground_t g = oc__ground(a->p, r);
  const double inv4pi = 1.0 / (4.0 * OC__PI), wphi = 2.0 * OC__PI / nphi;
  double L2[OC__MAX_COLS][3], F[3] = {0.0, 0.0, 0.0};
  memset(L2, 0, sizeof L2);
  oc__ray_t ray;
  oc__rows_t rows;
  oc__dirs_t dirs;
  for (int side = 0; side < 2; side++)
    for (int k = 0; k < a->rule_mu.n; k++) {
      double mu, wmu, Ts[3];
      double d = oc__dir_node(a, r, side, g.mu_h, k, n, mu_s, nphi, &mu, &wmu, &ray, &dirs);
      memset(dirs.L, 0, sizeof dirs.L);
      for (int q = 0; q < ray.n; q++) {
        double wts[3]; /* f's integrand; the azimuth integral of f is 2π (no sun) */
        for (int c = 0; c < 3; c++) {
          wts[c] = ray.w[q] * ray.T[q][c] * (ray.sR[q][c] + ray.sM[q]);
          F[c] += wmu * 2.0 * OC__PI * inv4pi * wts[c];
        }
        oc__rows_prepare(a, ray.r[q], 0, &rows);
        for (int i = 0; i < n; i++)
          for (int m = 0; m < nphi; m++) {
            oc__sun_T_rows(a, &rows, ray.r[q], ocg_atmo_cos_at(r, mu_s[i], dirs.nu[i][m], ray.t[q], ray.r[q]), Ts);
            for (int c = 0; c < 3; c++) dirs.L[i][m][c] += wts[c] * inv4pi * Ts[c];
          }
      }
      if (side == 1) oc__rows_prepare(a, g.b, 0, &rows);
      for (int i = 0; i < n; i++)
        for (int m = 0; m < nphi; m++) {
          if (side == 1) {
            double mus_g = ocg_atmo_cos_at(r, mu_s[i], dirs.nu[i][m], d, g.b);
            oc__sun_T_rows(a, &rows, g.b, mus_g, Ts);
            for (int c = 0; c < 3; c++) dirs.L[i][m][c] += exp(-ray.tau[c]) * g.brdf[c] * Ts[c] * fmax(mus_g, 0.0);
          }
          for (int c = 0; c < 3; c++) L2[i][c] += wmu * wphi * inv4pi * dirs.L[i][m][c];
        }
    }
  for (int i = 0; i < n; i++)
    for (int c = 0; c < 3; c++) out[i][c] = L2[i][c] / (1.0 - F[c]);
}

/* Sky radiance of every direction of one zenith-cosine node, per unit solar irradiance, into dirs->L:
 * single scattering (Rayleigh and Cornette–Shanks phases) plus Hillaire's multiple-scattering source
 * σ_s Ψ_ms:
 *   L(ω) = ∫_0^d T(0,s) [ (β_R(s) p_R(ν) + β^s_M(s) p_M(ν)) T_sun(s) + σ_s(s) Ψ_ms(s) ] ds. */
static void oc__sky_radiance(const struct oc_atmo_s *a, const oc__ray_t *ray, double r, int n, const double *mu_s,
                             int nphi, oc__dirs_t *dirs) {
  double pR[OC__MAX_COLS][OC__ATMO_MAX_PHI], pM[OC__MAX_COLS][OC__ATMO_MAX_PHI];
  oc__rows_t rows;
  memset(dirs->L, 0, sizeof dirs->L);
  for (int i = 0; i < n; i++)
    for (int m = 0; m < nphi; m++) {
      pR[i][m] = ocg_phase_rayleigh(dirs->nu[i][m]);
      pM[i][m] = ocg_phase_cornette_shanks(dirs->nu[i][m], a->p.mie_g);
    }
  for (int q = 0; q < ray->n; q++) {
    double wR[3], wM[3], wS[3], Ts[3], Ps[3];
    for (int c = 0; c < 3; c++) {
      double wt = ray->w[q] * ray->T[q][c];
      wR[c] = wt * ray->sR[q][c];
      wM[c] = wt * ray->sM[q];
      wS[c] = wR[c] + wM[c];
    }
    oc__rows_prepare(a, ray->r[q], 1, &rows);
    for (int i = 0; i < n; i++)
      for (int m = 0; m < nphi; m++) {
        double mus_q = ocg_atmo_cos_at(r, mu_s[i], dirs->nu[i][m], ray->t[q], ray->r[q]);
        oc__sun_T_rows(a, &rows, ray->r[q], mus_q, Ts);
        oc__psi_rows(a, &rows, ray->r[q], mus_q, Ps);
        for (int c = 0; c < 3; c++)
          dirs->L[i][m][c] += (wR[c] * pR[i][m] + wM[c] * pM[i][m]) * Ts[c] + wS[c] * Ps[c];
      }
  }
}

/* Sky irradiance on a horizontal surface, per unit solar irradiance: E(r, μs) = ∫_{μ>0} L(ω) μ dω
 * (side 0 of the horizon substitution with μ_h = 0, i.e. μ = s²). n values of μs. */
static void oc__eval_irradiance(const struct oc_atmo_s *a, double r, int n, const double *mu_s, double (*out)[3]) {
  const int nphi = OC_ATMO_PHI_NODES;
  const double wphi = 2.0 * OC__PI / nphi;
  oc__ray_t ray;
  oc__dirs_t dirs;
  memset(out, 0, sizeof(double[3]) * (size_t)n);
  for (int k = 0; k < a->rule_mu.n; k++) {
    double mu, wmu;
    oc__dir_node(a, r, 0, 0.0, k, n, mu_s, nphi, &mu, &wmu, &ray, &dirs);
    oc__sky_radiance(a, &ray, r, n, mu_s, nphi, &dirs);
    for (int i = 0; i < n; i++)
      for (int m = 0; m < nphi; m++)
        for (int c = 0; c < 3; c++) out[i][c] += wmu * wphi * mu * dirs.L[i][m][c];
  }
}

/* Sky fluence, per unit solar irradiance: Φ(r, μs) = ∫_4π L(ω) dω, with the ground seen below the
 * horizon as a Lambertian reflector lit by the sun and the sky:
 *   L_ground = T(0,d) (a/π) (T_sun(g) max(μ_s,g, 0) + E(b, μ_s,g))   (E from the irradiance table).
 * n values of μs. */
static void oc__eval_fluence(const struct oc_atmo_s *a, double r, int n, const double *mu_s, double (*out)[3]) {
  const int nphi = OC_ATMO_PHI_NODES;
  const oc__ground_t g = oc__ground(a->p, r);
  const double wphi = 2.0 * OC__PI / nphi;
  oc__ray_t ray;
  oc__rows_t ground;
  oc__dirs_t dirs;
  oc__rows_prepare(a, g.b, 0, &ground);
  memset(out, 0, sizeof(double[3]) * (size_t)n);
  for (int side = 0; side < 2; side++)
    for (int k = 0; k < a->rule_mu.n; k++) {
      double mu, wmu;
      double d = oc__dir_node(a, r, side, g.mu_h, k, n, mu_s, nphi, &mu, &wmu, &ray, &dirs);
      oc__sky_radiance(a, &ray, r, n, mu_s, nphi, &dirs);
      for (int i = 0; i < n; i++)
        for (int m = 0; m < nphi; m++) {
          if (side == 1) {
            double mus_g = ocg_atmo_cos_at(r, mu_s[i], dirs.nu[i][m], d, g.b), Ts[3], Eg[3];
            oc__sun_T_rows(a, &ground, g.b, mus_g, Ts);
            oc__rmus(a, 2, g.b, mus_g, Eg);
            for (int c = 0; c < 3; c++)
              dirs.L[i][m][c] += exp(-ray.tau[c]) * g.brdf[c] * (Ts[c] * fmax(mus_g, 0.0) + Eg[c]);
          }
          for (int c = 0; c < 3; c++) out[i][c] += wmu * wphi * dirs.L[i][m][c];
        }
    }
}

/* Row j of an (r, μs) table: every column's μs at once (the rays depend on r and μ only). */
static void oc__bake_rmus(struct oc_atmo_s *a, int which, int j) {
  oc__atmo_tab_t *tb = &a->tab[which];
  double r = ocg_atmo_rmus_from_uv(a->p, ocg_v2(0.5, (j + 0.5) / tb->h), tb->w, tb->h).x;
  double mu_s[OC__MAX_COLS], v[OC__MAX_COLS][3];
  for (int i = 0; i < tb->w; i++) mu_s[i] = ocg_atmo_rmus_from_uv(a->p, ocg_v2((i + 0.5) / tb->w, 0.5), tb->w, tb->h).y;
  if (which == 1) oc__eval_multiscatter(a, r, tb->w, mu_s, v);
  else if (which == 2) oc__eval_irradiance(a, r, tb->w, mu_s, v);
  else oc__eval_fluence(a, r, tb->w, mu_s, v);
  for (int i = 0; i < tb->w; i++) oc__store(tb->rgba + 4 * ((size_t)j * tb->w + i), v[i]);
}

void oc__atmo_bake_row(struct oc_atmo_s *a, int which, int row) {
  if (which == 0) oc__bake_transmittance(a, row);
  else if (which > 0 && which < OC__ATMO_NTABLES) oc__bake_rmus(a, which, row);
}

void oc__atmo_eval(const struct oc_atmo_s *a, int which, double r, double mu, double out[3]) {
  double v[1][3] = {{0.0, 0.0, 0.0}};
  r = fmin(fmax(r, a->p.bottom_radius), a->p.top_radius);
  mu = ocg_clamp_cos(mu);
  if (which == 0) {
    if (!ocg_atmo_ray_hits_ground(a->p, r, mu)) oc__eval_transmittance(a, r, mu, v[0]);
  } else if (which == 1) oc__eval_multiscatter(a, r, 1, &mu, v);
  else if (which == 2) oc__eval_irradiance(a, r, 1, &mu, v);
  else if (which == 3) oc__eval_fluence(a, r, 1, &mu, v);
  for (int c = 0; c < 3; c++) out[c] = v[0][c];
}
