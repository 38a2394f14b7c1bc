/* plot.h — a PNG plot drawn by hand into an RGB8 buffer (tools/plot.c), shared by the tools:
 * `overcast-bench sweep --plot` (error against render time: a scatter with its Pareto front) and
 * `overcast-stress --ramp --plot` (figures against the number of viewers: one line per budget).
 * Not part of the project's API: tools/ only. */
#ifndef OC_TOOLS_PLOT_H
#define OC_TOOLS_PLOT_H

#include <stddef.h>

#define OCTS_PLOT_GROUPS 10

typedef struct {
  double x, y;           /**< e.g. render ms and RMSE; a point with a non-finite coordinate is not drawn */
  int group;             /**< colour, 0..OCTS_PLOT_GROUPS-1 */
  int pareto, reference;
  char label[40];        /**< drawn next to Pareto points */
} octs_plot_point_t;

typedef struct {
  const char *title, *subtitle, *xlabel, *ylabel;
  const char *note;      /**< text under the legend (lines split at newlines), or NULL */
  const char *group_name[OCTS_PLOT_GROUPS];
  int ngroups;
  int lines;             /**< join each group's points in order of x, in the group's colour */
  double ymin_top;       /**< the y axis reaches at least this (0: the data decide) */
  double hline;          /**< a dashed horizontal line at this y (NAN or 0: none) */
  const char *hline_label;
} octs_plot_desc_t;

/*! octs_plot_png() : the scatter plot, the Pareto front joined in order of x, as an RGB PNG.
 *  Labels need stb_easy_font (libstb-dev); without it the plot has no text. The legend names
 *  the Pareto front and the reference only when some point is one.
 *  @return 0 or OC_E* with why. */
int octs_plot_png(const char *path, const octs_plot_point_t *p, int n, const octs_plot_desc_t *d, char *why, size_t why_len);

#endif /* OC_TOOLS_PLOT_H */
