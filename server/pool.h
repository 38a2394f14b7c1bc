/* pool.h — a fixed set of worker threads running parallel loops (brick production).
 *
 * ocs_pool_run() hands out indices 0..n-1 through an atomic counter and returns when all are done,
 * so each index's result can go to its own slot and the output does not depend on the thread
 * count. The calling thread works too: a pool of 1 thread spawns nothing. */
#ifndef OC_SERVER_POOL_H
#define OC_SERVER_POOL_H

#include <stddef.h>

#define OCS_POOL_MAX_THREADS 64

typedef struct ocs_pool_s ocs_pool_t;
/* One unit of work; a negative return is remembered (the first one) and returned by run(). */
typedef int (*ocs_pool_fn)(void *ctx, size_t index, int worker);

/*! ocs_pool_create() : threads 1..64 (0 → the number of online CPUs, at most 64), including the
 *  caller. @return 0, OC_EINVAL or OC_ENOMEM. */
int ocs_pool_create(ocs_pool_t **out, int threads);
/*! ocs_pool_create_niced() : nice 0 is ocs_pool_create(). nice 1..19: every thread is spawned and
 *  runs at that nice value (lower priority than the caller's threads), and run() only waits: a
 *  server's producers then yield the cores to its ticks and its sockets. */
int ocs_pool_create_niced(ocs_pool_t **out, int threads, int nice);
void ocs_pool_free(ocs_pool_t *p);
int ocs_pool_threads(const ocs_pool_t *p);
/*! ocs_pool_run() : fn(ctx, i, worker) for every i < n, worker in 0..threads-1; blocks until all
 *  are done. Not reentrant: one run at a time per pool. @return 0 or the first negative fn result. */
int ocs_pool_run(ocs_pool_t *p, size_t n, ocs_pool_fn fn, void *ctx);

#endif /* OC_SERVER_POOL_H */
