/* procedural_columns.c — placeholder */
#include "procedural.h"
int ocs__proc_sample_columns(const ocs_source_t *s, oc_key_t key, double t, float out[OC_BRICK_VOXELS]) { return ocs__proc_sample_strata(s, key, t, out); }
