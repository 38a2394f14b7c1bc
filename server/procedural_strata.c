/* procedural_strata.c — the procedural planet's exact box filter (procedural.h): each sample is
 * the mean of the finest σt, ocs__eval_point()'s value, over stratified midpoints of its
 * footprint (docs/procedural.md, "Filtering"). The oracle of the fast estimate
 * (procedural_columns.c) and of the Conventions' filter tests.
 *
 * Speed without changing a bit: the noise is the batch fBm over the sub-samples of a brick;
 * points outside every active band are skipped (they are 0); per voxel a bound drops the layers
 * that are 0 there and marks those whose coverage ramp is exactly 1; each layer evaluates its
 * cheaper pattern first and the detail only where G > 0; coarse voxels walk their strata column
 * by column, each column only over the strata that can meet the band. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "oc_err.h"
#include "procedural.h"

#define OCS__CHUNK 512 /* points per batch pass: the scratch stays in L1/L2 */

/*-*** Bricks ***/

typedef struct {
  int n;
  double p[3 * OCS__CHUNK], r[OCS__CHUNK], h[OCS__CHUNK], sig[OCS__CHUNK];
  uint16_t vox[OCS__CHUNK];
  uint8_t mask[OCS__CHUNK], wone[OCS__CHUNK]; /* the voxel's ocs__bb_t mask and wone */
  /* per-layer scratch */
  int idx[OCS__CHUNK], sel[OCS__CHUNK];
  double q[3 * OCS__CHUNK], xyz[3 * OCS__CHUNK], w[OCS__CHUNK], v[OCS__CHUNK];
  float val[OCS__CHUNK];
  double sum[OC_BRICK_VOXELS];
} ocs__ws_t;

/* One layer over the chunk's points in three batch passes; each pass keeps only the points that
 * can still be non-zero, which skips exactly the work whose result could only be 0 (G = W·V - Q
 * with W the coverage ramp and V = sat(a0 + a1·K) the cell ramp: when either is 0, G ≤ 0).
 * Layers whose cells are mostly empty (a0 ≤ 0: cumulus, cumulonimbus) evaluate the cheaper cell
 * noise first; where the voxel's bound proved W = 1, the coverage noise is not evaluated at all.
 * The value of each point is that of ocs__layer_point() whatever the order. Adds σt to ws->sig in
 * layer order, as ocs__eval_point() does. */
static void ocs__layer_batch(const ocs__proc_t *P, const ocs__frame_t *F, int l, ocs__ws_t *ws) {
  const ocs__layer_t *L = &ocs__layers[l];
  const ocs__lstate_t *S = &P->L[l];
  const ocs__lframe_t *lf = &F->l[l];
  int m = 0;
  for (int i = 0; i < ws->n; i++)
    if ((ws->mask[i] >> l & 1u) && ws->h[i] >= S->band_lo && ws->h[i] <= S->band_hi) {
      double *q = &ws->q[3 * m];
      ocs__rotate(lf->M, &ws->p[3 * i], q);
      ws->w[m] = 1.0; /* W, until computed */
      ws->v[m] = 1.0; /* V, until computed */
      ws->idx[m++] = i;
    }
  int cell_first = L->a0 <= 0.0;
  for (int pass = 0; pass < 2 && m > 0; pass++) {
    int cov = (pass == 0) != cell_first;
    int n = 0;
    for (int j = 0; j < m; j++) {
      int i = ws->idx[j];
      if (cov && (ws->wone[i] >> l & 1u)) continue; /* W = 1 exactly */
      const double *q = &ws->q[3 * j];
      double X[3], s = OCS__R / ws->r[i];
      X[0] = q[0] * s, X[1] = q[1] * s, X[2] = q[2] * s;
      ocs__coords(S, cov ? OCS__COV : OCS__CELL, X, lf->off[cov ? OCS__COV : OCS__CELL], &ws->xyz[3 * n]);
      ws->sel[n++] = j;
    }
    oc_fbm3_batch(ws->xyz, n, cov ? &S->fcov : &S->fcell, ws->val);
    for (int t = 0; t < n; t++) {
      int j = ws->sel[t];
      if (cov)
        ws->w[j] = ocs__w(L, lf, ws->val[t]);
      else
        ws->v[j] = ocs__v(L, ws->val[t]);
    }
    int k = 0; /* compact the survivors */
    for (int j = 0; j < m; j++) {
      if (!(ws->w[j] > 0.0) || !(ws->v[j] > 0.0)) continue;
      if (k != j) {
        ws->idx[k] = ws->idx[j], ws->w[k] = ws->w[j], ws->v[k] = ws->v[j];
        memcpy(&ws->q[3 * k], &ws->q[3 * j], 3 * sizeof(double));
      }
      k++;
    }
    m = k;
  }
  int k = 0;
  for (int j = 0; j < m; j++) {
    double G = ws->w[j] * ws->v[j] - ocs__q(L, ws->h[ws->idx[j]]);
    if (!(G > 0.0)) continue;
    ws->idx[k] = ws->idx[j], ws->w[k] = G;
    if (k != j) memcpy(&ws->q[3 * k], &ws->q[3 * j], 3 * sizeof(double));
    k++;
  }
  m = k;
  if (!m) return;
  for (int j = 0; j < m; j++) ocs__coords(S, OCS__DET, &ws->q[3 * j], lf->off[OCS__DET], &ws->xyz[3 * j]);
  oc_fbm3_batch(ws->xyz, m, &lf->det, ws->val);
  for (int j = 0; j < m; j++) {
    int i = ws->idx[j];
    ws->sig[i] += ocs__sigma(L, F, lf, ws->w[j], ws->val[j], ws->h[i]);
  }
}

static void ocs__flush(const ocs__proc_t *P, const ocs__frame_t *F, ocs__ws_t *ws) {
  for (int i = 0; i < ws->n; i++) ws->sig[i] = 0.0;
  for (int l = 0; l < OCS_LAYER_COUNT; l++)
    if (F->mask >> l & 1u) ocs__layer_batch(P, F, l, ws);
  /* In point order: each voxel's points are contiguous and in ocs_brick_sample()'s order. */
  for (int i = 0; i < ws->n; i++) ws->sum[ws->vox[i]] += ws->sig[i];
  ws->n = 0;
}

/* A point of voxel v into the batch if it lies in [band_lo, band_hi] (outside, every layer is
 * exactly 0). r is computed as |p| always is, so the points' values do not depend on the path. */
static inline void ocs__add_point(const ocs__proc_t *P, const ocs__frame_t *F, ocs__ws_t *ws, const double xyz[3],
                                  double band_lo, double band_hi, int v, const ocs__bb_t *vb) {
  double x = xyz[0], y = xyz[1], z = xyz[2];
  double r = sqrt(x * x + y * y + z * z), h = r - OCS__R;
  if (!(h >= band_lo && h <= band_hi)) return;
  int at = ws->n++;
  ws->p[3 * at] = x, ws->p[3 * at + 1] = y, ws->p[3 * at + 2] = z;
  ws->r[at] = r, ws->h[at] = h;
  ws->vox[at] = (uint16_t)v;
  ws->mask[at] = (uint8_t)vb->mask;
  ws->wone[at] = (uint8_t)vb->wone;
  if (ws->n == OCS__CHUNK) ocs__flush(P, F, ws);
}

/* The strata m of a column whose vertical coordinate t(m) = -S + (g + (m + ½)/n - ½)·u can meet
 * the band: with a2 the squared horizontal distance from the axis, R + band_lo ≤ √(a2 + t²) ≤ R +
 * band_hi holds only for |t| in [t_lo, t_hi]. Solved for m in closed form, widened by two strata
 * for rounding (far more than the ~1e-9 relative error of the inversion), clamped, as at most two
 * increasing runs m0[i]..m1[i]. @return the number of runs (0: the column misses the band). */
static int ocs__column_range(double a2, double band_lo, double band_hi, double g, double u, int n, int m0[2],
                             int m1[2]) {
  double rlo = OCS__R + band_lo, rhi = OCS__R + band_hi;
  double hi2 = rhi * rhi - a2, lo2 = rlo * rlo - a2;
  if (!(hi2 > -1e-6 * rhi * rhi)) return 0; /* a column within ~3 m of the top still counts */
  double t_hi = sqrt(hi2 > 0.0 ? hi2 : 0.0), t_lo = lo2 > 0.0 ? sqrt(lo2) : 0.0;
  /* m(t) = ((t + S)/u - g + ½)·n - ½, increasing in t */
  double ta[2] = {-t_hi, t_lo}, tb[2] = {-t_lo, t_hi};
  int runs = 0;
  for (int k = 0; k < 2; k++) {
    double a = ((ta[k] + OC_ROOT_HALF) / u - g + 0.5) * (double)n - 0.5;
    double b = ((tb[k] + OC_ROOT_HALF) / u - g + 0.5) * (double)n - 0.5;
    if (!(b >= -2.0) || !(a <= (double)n + 1.0)) continue;
    int lo = a < 2.0 ? 0 : (int)floor(a) - 2, hi = b > (double)n - 3.0 ? n - 1 : (int)ceil(b) + 2;
    if (runs && lo <= m1[runs - 1] + 1) { /* overlaps the first run (t_lo small): one run */
      if (hi > m1[runs - 1]) m1[runs - 1] = hi;
      continue;
    }
    m0[runs] = lo, m1[runs] = hi;
    runs++;
  }
  return runs;
}

/* Strata of a level: sub_h along the two most horizontal axes, sub_v along the most vertical. */
static int ocs__strata(int level, double spacing, int max) {
  double n = ceil(ocs__voxel_size(level) / spacing);
  return n < OCS_PROC_SUB ? OCS_PROC_SUB : (n > max ? max : (int)n);
}
void ocs__subs(int level, int *sub_h, int *sub_v) {
  *sub_h = ocs__strata(level, OCS_PROC_DH, OCS_PROC_MAX_SUB_H);
  *sub_v = ocs__strata(level, OCS_PROC_DZ, OCS_PROC_MAX_SUB_V);
}

int ocs__proc_sample_strata(const ocs_source_t *s, oc_key_t key, double t, float out[OC_BRICK_VOXELS]) {
  if (!out) return OC_EINVAL;
  ocs__brick_t B;
  int r = ocs__brick_begin(s, key, t, &B);
  if (r <= 0) return r;
  const ocs__proc_t *P = B.P;

  int sub_h, sub_v;
  ocs__subs(B.level, &sub_h, &sub_v);
  double off_h[OCS_PROC_MAX_SUB_H], off_v[OCS_PROC_MAX_SUB_V];
  for (int m = 0; m < sub_h; m++) off_h[m] = ((double)m + 0.5) / (double)sub_h - 0.5;
  for (int m = 0; m < sub_v; m++) off_v[m] = ((double)m + 0.5) / (double)sub_v - 0.5;
  ocs__ws_t *ws = malloc(sizeof *ws);
  if (!ws) return OC_ENOMEM;
  ws->n = 0;
  memset(ws->sum, 0, sizeof ws->sum);
  double inv[OC_BRICK_VOXELS];
  uint32_t ic[3];
  oc_key_coords(key, &ic[0], &ic[1], &ic[2]);
  double u = ocs__voxel_size(B.level);
  uint8_t vmask[OC_BRICK_VOXELS], vwone[OC_BRICK_VOXELS];
  ocs__voxel_bounds(&B, key, vmask, vwone, NULL);

  for (int k = 0; k < 8; k++)
    for (int j = 0; j < 8; j++)
      for (int i = 0; i < 8; i++) {
        int v = i + 8 * j + 64 * k;
        double gg[3], c[3];
        /* The strata's shape depends only on the sample's own position, so a face sample shared
         * with a neighbour gets the same points from either brick. */
        int va = ocs__voxel_centre(ic, v, u, gg, c);
        int n[3] = {sub_h, sub_h, sub_h};
        n[va] = sub_v;
        inv[v] = 1.0 / ((double)n[0] * n[1] * n[2]);
        if (!vmask[v]) continue;
        ocs__bb_t vb = {.mask = vmask[v], .wone = vwone[v]};
        unsigned vm = vb.mask;
        double band_lo = INFINITY, band_hi = -INFINITY;
        for (int l = 0; l < OCS_LAYER_COUNT; l++)
          if (vm >> l & 1u) {
            band_lo = fmin(band_lo, P->L[l].band_lo);
            band_hi = fmax(band_hi, P->L[l].band_hi);
          }
        if (n[va] == sub_h) { /* isotropic: ocs_brick_sample()'s order, so the sums are its bits */
          for (int mz = 0; mz < sub_h; mz++) {
            double z = -OC_ROOT_HALF + (gg[2] + off_h[mz]) * u;
            for (int my = 0; my < sub_h; my++) {
              double y = -OC_ROOT_HALF + (gg[1] + off_h[my]) * u;
              for (int mx = 0; mx < sub_h; mx++) {
                double xyz[3] = {-OC_ROOT_HALF + (gg[0] + off_h[mx]) * u, y, z};
                ocs__add_point(P, &B.F, ws, xyz, band_lo, band_hi, v, &vb);
              }
            }
          }
          continue;
        }
        /* Anisotropic (coarse): column by column along the vertical axis, each column's strata
         * limited to those that can meet the band (ocs__column_range); the exact test still
         * decides each point. */
        int ha = va == 0 ? 1 : 0, hb = va == 2 ? 1 : 2;
        for (int mb = 0; mb < sub_h; mb++)
          for (int ma = 0; ma < sub_h; ma++) {
            double xyz[3];
            xyz[ha] = -OC_ROOT_HALF + (gg[ha] + off_h[ma]) * u;
            xyz[hb] = -OC_ROOT_HALF + (gg[hb] + off_h[mb]) * u;
            int m0[2], m1[2];
            int runs = ocs__column_range(xyz[ha] * xyz[ha] + xyz[hb] * xyz[hb], band_lo, band_hi, gg[va], u, sub_v, m0, m1);
            for (int run = 0; run < runs; run++)
              for (int m = m0[run]; m <= m1[run]; m++) {
                xyz[va] = -OC_ROOT_HALF + (gg[va] + off_v[m]) * u;
                ocs__add_point(P, &B.F, ws, xyz, band_lo, band_hi, v, &vb);
              }
          }
      }
  ocs__flush(P, &B.F, ws);
  for (int v = 0; v < OC_BRICK_VOXELS; v++)
    if (ws->sum[v] > 0.0) out[v] += (float)(ws->sum[v] * inv[v]);
  free(ws);
  return 0;
}
