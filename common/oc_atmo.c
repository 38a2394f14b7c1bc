/* oc_atmo.c — the public (float) side of the atmosphere: parameters, validation, threads, look-ups.
 * The numerics are in oc_atmo_bake.c (double precision); see oc_atmo_internal.h for why there are
 * two translation units. */
#include "oc_atmo.h"

#include <math.h>      /* isfinite */
#include <stdlib.h>    /* calloc */
#include <time.h>      /* clock_gettime */
#include <unistd.h>    /* sysconf */

#include "oc_atmo_internal.h"
#include "oc_err.h"
#include "oc_log.h"
#include "oc_parallel.h"
#include "oc_planet.h" /* OC_PLANET_RADIUS, OC_ATMOSPHERE_HEIGHT */

#define OC__ATMO_MAX_THREADS 64

void oc_atmo_params_default(ocg_atmosphere *p) {
  if (!p) return;
  *p = (ocg_atmosphere){0};
  p->bottom_radius = (float)OC_PLANET_RADIUS;
  p->top_radius = (float)(OC_PLANET_RADIUS + OC_ATMOSPHERE_HEIGHT);
  p->rayleigh_scattering = ocg_v3(5.802e-6f, 13.558e-6f, 33.1e-6f);
  p->rayleigh_scale_height = 8000.0f;
  p->mie_scattering = 3.996e-6f;
  p->mie_extinction = 4.44e-6f;
  p->mie_scale_height = 1200.0f;
  p->mie_g = 0.8f;
  p->ozone_absorption = ocg_v3(0.650e-6f, 1.881e-6f, 0.085e-6f);
  p->ozone_center = 25000.0f;
  p->ozone_half_width = 15000.0f;
  /* Land, not Bruneton's grey 0.1: a mix of vegetation and soil (green above red, little blue), so
   * that the planet's ground reads as land beside the clouds (issue 21, "a first frame worth
   * opening"; `overcast-bench look` gives its colour). */
  p->ground_albedo = ocg_v3(0.07f, 0.09f, 0.04f);
  p->sun_angular_radius = 0.004675f;
  p->solar_irradiance = ocg_v3(1.474f, 1.8504f, 1.91198f);
}

/* ---- Validation --------------------------------------------------------------------------------------- */

static int oc__in(double x, double lo, double hi) { return isfinite(x) && x >= lo && x <= hi; }
static int oc__in3(ocg_vec3 v, double lo, double hi) { return oc__in(v.x, lo, hi) && oc__in(v.y, lo, hi) && oc__in(v.z, lo, hi); }

static int oc__bad(const char *field, const char *rule) {
  oc_log_error("oc_atmo_create: bad parameter %s (%s)", field, rule);
  return OC_EINVAL;
}

static int oc__check(const ocg_atmosphere *p) {
  if (!p) return oc__bad("params", "NULL");
  if (!oc__in(p->bottom_radius, 1.0, 1e9)) return oc__bad("bottom_radius", "must be in [1, 1e9] m");
  if (!(oc__in(p->top_radius, 0.0, 1e9) && p->top_radius > p->bottom_radius))
    return oc__bad("top_radius", "must be finite and > bottom_radius");
  if (!oc__in3(p->rayleigh_scattering, 0.0, 1.0)) return oc__bad("rayleigh_scattering", "each must be in [0, 1] m^-1");
  if (!(oc__in(p->rayleigh_scale_height, 0.0, 1e9) && p->rayleigh_scale_height > 0.0f))
    return oc__bad("rayleigh_scale_height", "must be > 0 m");
  if (!oc__in(p->mie_scattering, 0.0, 1.0)) return oc__bad("mie_scattering", "must be in [0, 1] m^-1");
  if (!(oc__in(p->mie_extinction, 0.0, 1.0) && p->mie_extinction >= p->mie_scattering))
    return oc__bad("mie_extinction", "must be in [mie_scattering, 1] m^-1");
  if (!(oc__in(p->mie_scale_height, 0.0, 1e9) && p->mie_scale_height > 0.0f))
    return oc__bad("mie_scale_height", "must be > 0 m");
  if (!(oc__in(p->mie_g, -1.0, 1.0) && p->mie_g > -1.0f && p->mie_g < 1.0f)) return oc__bad("mie_g", "must be in (-1, 1)");
  if (!oc__in3(p->ozone_absorption, 0.0, 1.0)) return oc__bad("ozone_absorption", "each must be in [0, 1] m^-1");
  if (!oc__in(p->ozone_center, -1e9, 1e9)) return oc__bad("ozone_center", "must be finite");
  if (!(oc__in(p->ozone_half_width, 0.0, 1e9) && p->ozone_half_width > 0.0f))
    return oc__bad("ozone_half_width", "must be > 0 m");
  if (!oc__in3(p->ground_albedo, 0.0, 1.0)) return oc__bad("ground_albedo", "each must be in [0, 1]");
  if (!(oc__in(p->sun_angular_radius, 0.0, 0.1) && p->sun_angular_radius > 0.0f))
    return oc__bad("sun_angular_radius", "must be in (0, 0.1] rad");
  if (!oc__in3(p->solar_irradiance, 0.0, 1e30)) return oc__bad("solar_irradiance", "each must be finite and >= 0");
  return 0;
}

/* ---- Threads ------------------------------------------------------------------------------------------ */

typedef struct {
  oc_atmo_t *a;
  int which;
} oc__job_t;

/* Row `row` of a table (an oc_parallel() item): every texel is a pure function of the parameters and
 * the tables before it, so the result does not depend on which thread computes which row. */
static void oc__bake_row(void *arg, int row, int thread) {
  (void)thread;
  oc__job_t *job = arg;
  oc__atmo_bake_row(job->a, job->which, row);
}

static void oc__run(oc_atmo_t *a, int which, int threads) {
  oc__job_t job = {.a = a, .which = which};
  oc_parallel(a->tab[which].h, threads, oc__bake_row, &job);
}

/* ---- Life cycle --------------------------------------------------------------------------------------- */

oc_atmo_t *oc_atmo_create(const ocg_atmosphere *p, int threads) {
  if (oc__check(p) < 0) return NULL;
  if (threads <= 0) {
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    threads = n > 0 ? (int)n : 1;
  }
  if (threads > OC__ATMO_MAX_THREADS) threads = OC__ATMO_MAX_THREADS;

  oc_atmo_t *a = calloc(1, sizeof *a);
  if (!a) goto nomem;
  a->p = *p;
  a->p.reserved0 = a->p.reserved1 = 0.0f;
  static const int size[OC__ATMO_NTABLES][2] = {
      {OCG_ATMO_TRANSMITTANCE_W, OCG_ATMO_TRANSMITTANCE_H},
      {OCG_ATMO_MULTISCATTER_W, OCG_ATMO_MULTISCATTER_H},
      {OCG_ATMO_IRRADIANCE_W, OCG_ATMO_IRRADIANCE_H},
      {OCG_ATMO_IRRADIANCE_W, OCG_ATMO_IRRADIANCE_H},
  };
  for (int k = 0; k < OC__ATMO_NTABLES; k++) {
    a->tab[k].w = size[k][0];
    a->tab[k].h = size[k][1];
    a->tab[k].rgba = calloc((size_t)size[k][0] * size[k][1] * 4, sizeof(float));
    if (!a->tab[k].rgba) goto nomem;
  }
  oc__atmo_prepare(a);

  double ms[OC__ATMO_NTABLES];
  for (int k = 0; k < OC__ATMO_NTABLES; k++) { /* each table needs the ones before it */
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    oc__run(a, k, threads);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    ms[k] = (t1.tv_sec - t0.tv_sec) * 1e3 + (t1.tv_nsec - t0.tv_nsec) * 1e-6;
  }
  oc_log_debug("atmosphere tables on %d threads: transmittance %.1f ms, multiscatter %.1f ms, irradiance %.1f ms, "
               "fluence %.1f ms",
               threads, ms[0], ms[1], ms[2], ms[3]);
  return a;

nomem:
  oc_log_error("oc_atmo_create: out of memory");
  oc_atmo_free(a);
  return NULL;
}

void oc_atmo_free(oc_atmo_t *a) {
  if (!a) return;
  for (int k = 0; k < OC__ATMO_NTABLES; k++) free(a->tab[k].rgba);
  free(a);
}

const ocg_atmosphere *oc_atmo_params(const oc_atmo_t *a) { return a ? &a->p : NULL; }

int oc_atmo_table(const oc_atmo_t *a, int which, int *w, int *h, const float **rgba) {
  if (!a || !w || !h || !rgba || which < 0 || which >= OC__ATMO_NTABLES) return OC_EINVAL;
  *w = a->tab[which].w;
  *h = a->tab[which].h;
  *rgba = a->tab[which].rgba;
  return 0;
}

/* ---- Look-ups ----------------------------------------------------------------------------------------- */

static ocg_vec3 oc__v3(const double o[3]) { return ocg_v3((float)o[0], (float)o[1], (float)o[2]); }

ocg_vec3 oc_atmo_transmittance(const oc_atmo_t *a, double r, double mu) {
  double o[3] = {0.0, 0.0, 0.0};
  if (a) oc__atmo_transmittance(a, r, mu, o);
  return oc__v3(o);
}

ocg_vec3 oc_atmo_sun_transmittance(const oc_atmo_t *a, double r, double mu_s) {
  double o[3] = {0.0, 0.0, 0.0};
  if (a) oc__atmo_sun_transmittance(a, r, mu_s, o);
  return oc__v3(o);
}

ocg_vec3 oc_atmo_multiscatter(const oc_atmo_t *a, double r, double mu_s) {
  double o[3] = {0.0, 0.0, 0.0};
  if (a) oc__atmo_rmus_lookup(a, OC_ATMO_TABLE_MULTISCATTER, r, mu_s, o);
  return oc__v3(o);
}

ocg_vec3 oc_atmo_sky_irradiance(const oc_atmo_t *a, double r, double mu_s) {
  double o[3] = {0.0, 0.0, 0.0};
  if (a) oc__atmo_rmus_lookup(a, OC_ATMO_TABLE_IRRADIANCE, r, mu_s, o);
  return oc__v3(o);
}

ocg_vec3 oc_atmo_sky_fluence(const oc_atmo_t *a, double r, double mu_s) {
  double o[3] = {0.0, 0.0, 0.0};
  if (a) oc__atmo_rmus_lookup(a, OC_ATMO_TABLE_FLUENCE, r, mu_s, o);
  return oc__v3(o);
}
