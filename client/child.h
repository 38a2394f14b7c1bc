/* child.h — overcast-server as a child process: started on an address it prints ("listening on
 * HOST:PORT", port 0 picking a free one), killed if we die, stopped with SIGTERM. overcast-view's
 * --scene mode and overcast-stress start the overcast-server next to them this way. */
#ifndef OC_CLIENT_CHILD_H
#define OC_CLIENT_CHILD_H

#include <stddef.h>
#include <sys/types.h>

#include "net.h" /* OCV_HOST_MAX */

typedef struct {
  pid_t pid;  /**< -1: none */
  int out_fd; /**< its stdout (kept open, never read after the address); -1: none */
  char host[OCV_HOST_MAX];
  int port;
} ocv_child_t;

/*! ocv_child_spawn() : runs argv[0] with argv (its stdout to a pipe, stderr shared, killed if we
 *  die) and reads its "listening on HOST:PORT" within timeout_s. @return 0 or OC_EIO with a reason. */
int ocv_child_spawn(char *const argv[], double timeout_s, ocv_child_t *c, char *why, size_t why_len);
/*! ocv_child_stop() : SIGTERM, waits up to timeout_s (then SIGKILL). @return its exit status,
 *  128 + signal when killed by one, or -1. */
int ocv_child_stop(ocv_child_t *c, double timeout_s);
/*! ocv_child_kill() : SIGKILL (a crash, as far as its clients can tell) and wait. @return as above. */
int ocv_child_kill(ocv_child_t *c);
/*! ocv_exe_dir() : the folder of this program (/proc/self/exe). @return 0 or -1. */
int ocv_exe_dir(char *buf, size_t cap);

#endif /* OC_CLIENT_CHILD_H */
