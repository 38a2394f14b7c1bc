/* prom_text.c — the Prometheus text exposition format (prom_text.h). */
#include "prom_text.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int ocs_prom_number(char *out, size_t cap, double v) {
  if (isnan(v)) return snprintf(out, cap, "NaN");
  if (isinf(v)) return snprintf(out, cap, v > 0 ? "+Inf" : "-Inf");
  int n = 0;
  for (int prec = 15; prec <= 17; prec++) { /* 17 digits always read back; fewer mostly do, and read better */
    n = snprintf(out, cap, "%.*g", prec, v);
    if (strtod(out, NULL) == v) break;
  }
  return n;
}

static void put_str(oc_buf_t *b, const char *s) { oc_buf_append(b, s, strlen(s)); }

/* s with backslash and newline escaped, and the double quote too when `quote` (label values). */
static void put_escaped(oc_buf_t *b, const char *s, int quote) {
  for (; *s; s++) {
    if (*s == '\\') put_str(b, "\\\\");
    else if (*s == '\n') put_str(b, "\\n");
    else if (*s == '"' && quote) put_str(b, "\\\"");
    else oc_buf_u8(b, (uint8_t)*s);
  }
}

static void put_number(oc_buf_t *b, double v) {
  char num[40];
  ocs_prom_number(num, sizeof num, v);
  put_str(b, num);
}

void ocs_prom_family(oc_buf_t *b, const char *name, const char *type, const char *help) {
  put_str(b, "# HELP ");
  put_str(b, name);
  oc_buf_u8(b, ' ');
  put_escaped(b, help, 0);
  put_str(b, "\n# TYPE ");
  put_str(b, name);
  oc_buf_u8(b, ' ');
  put_str(b, type);
  oc_buf_u8(b, '\n');
}

void ocs_prom_sample(oc_buf_t *b, const char *name, const char *label, const char *label_value, double v) {
  put_str(b, name);
  if (label) {
    oc_buf_u8(b, '{');
    put_str(b, label);
    put_str(b, "=\"");
    put_escaped(b, label_value, 1);
    put_str(b, "\"}");
  }
  oc_buf_u8(b, ' ');
  put_number(b, v);
  oc_buf_u8(b, '\n');
}

/* name with a suffix (_bucket, _sum, _count) */
static void suffixed(char *out, size_t cap, const char *name, const char *suffix) { snprintf(out, cap, "%s%s", name, suffix); }

void ocs_prom_histogram(oc_buf_t *b, const char *name, const char *help, const ocs_hist_view_t *h) {
  char sample[160], le[40];
  ocs_prom_family(b, name, "histogram", help);
  suffixed(sample, sizeof sample, name, "_bucket");
  for (int i = 0; h->le && i < OCS_HIST_BUCKETS; i++) { /* le NULL: a histogram never set up, +Inf only */
    ocs_prom_number(le, sizeof le, h->le[i]);
    ocs_prom_sample(b, sample, "le", le, (double)h->cum[i]);
  }
  ocs_prom_sample(b, sample, "le", "+Inf", (double)h->n);
  suffixed(sample, sizeof sample, name, "_sum");
  ocs_prom_sample(b, sample, NULL, NULL, h->sum);
  suffixed(sample, sizeof sample, name, "_count");
  ocs_prom_sample(b, sample, NULL, NULL, (double)h->n);
}
