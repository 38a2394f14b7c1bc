/* oc_parallel.h — one parallel loop for the CPU's row and chunk loops (the reference renderer, the
 * atmosphere bake, the benches): items go to threads through an atomic counter, and each item writes
 * only its own outputs, so results never depend on the thread count. */
#ifndef OC_COMMON_PARALLEL_H
#define OC_COMMON_PARALLEL_H

#define OC_PARALLEL_MAX_THREADS 256 /**< more are run as this many */

/*! oc_parallel() : calls fn(ctx, item, thread) once for every item of [0, count), on `threads`
 *  threads (at most OC_PARALLEL_MAX_THREADS, and no more than count); thread 0 is the caller's. A
 *  thread that fails to start leaves its items to the others. Returns once every item is done. */
void oc_parallel(int count, int threads, void (*fn)(void *ctx, int item, int thread), void *ctx);

#endif /* OC_COMMON_PARALLEL_H */
