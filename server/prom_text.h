/* prom_text.h — the Prometheus text exposition format (version 0.0.4) written into a buffer: a
 * family's HELP and TYPE lines, its samples (at most one label), histograms read from
 * ocs_hist_view_t. Escaping and number formatting follow the format's rules, so that promtool
 * and Prometheus parse whatever label values and numbers come. */
#ifndef OC_SERVER_PROM_TEXT_H
#define OC_SERVER_PROM_TEXT_H

#include <stddef.h>

#include "histogram.h"
#include "oc_bytes.h"

/* The Content-Type of a scrape's answer. */
#define OCS_PROM_CONTENT_TYPE "text/plain; version=0.0.4; charset=utf-8"

/*! ocs_prom_number() : v as the format writes it: the shortest decimal that reads back as v
 *  ("0.0001", "12345", "1e+300"), "+Inf", "-Inf" or "NaN". @return its length. */
int ocs_prom_number(char *out, size_t cap, double v);
/*! ocs_prom_family() : "# HELP name help" (backslashes and newlines escaped) and
 *  "# TYPE name type" (counter, gauge, histogram). */
void ocs_prom_family(oc_buf_t *b, const char *name, const char *type, const char *help);
/*! ocs_prom_sample() : "name value", or "name{label="value"} v" when label is not NULL (the value
 *  with backslashes, quotes and newlines escaped). */
void ocs_prom_sample(oc_buf_t *b, const char *name, const char *label, const char *label_value, double v);
/*! ocs_prom_histogram() : a histogram family: its HELP and TYPE, a cumulative name_bucket per upper
 *  bound and le="+Inf" (the count), name_sum and name_count. */
void ocs_prom_histogram(oc_buf_t *b, const char *name, const char *help, const ocs_hist_view_t *h);

#endif /* OC_SERVER_PROM_TEXT_H */
