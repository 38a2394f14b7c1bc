/* oc_parallel.c — see oc_parallel.h. */
#include "oc_parallel.h"

#include <pthread.h>   /* pthread_create */
#include <stdatomic.h> /* atomic_int */

typedef struct {
  atomic_int next;
  int count;
  void (*fn)(void *ctx, int item, int thread);
  void *ctx;
} oc__loop_t;

typedef struct {
  oc__loop_t *loop;
  int id;
} oc__loop_thread_t;

static void *oc__loop_work(void *arg) {
  oc__loop_thread_t *t = arg;
  oc__loop_t *l = t->loop;
  for (int i; (i = atomic_fetch_add(&l->next, 1)) < l->count;) l->fn(l->ctx, i, t->id);
  return NULL;
}

void oc_parallel(int count, int threads, void (*fn)(void *ctx, int item, int thread), void *ctx) {
  oc__loop_t loop = {.count = count, .fn = fn, .ctx = ctx};
  atomic_init(&loop.next, 0);
  if (threads > OC_PARALLEL_MAX_THREADS) threads = OC_PARALLEL_MAX_THREADS;
  if (threads > count) threads = count;
  pthread_t th[OC_PARALLEL_MAX_THREADS];
  oc__loop_thread_t t[OC_PARALLEL_MAX_THREADS];
  int ok[OC_PARALLEL_MAX_THREADS] = {0};
  t[0] = (oc__loop_thread_t){&loop, 0};
  for (int i = 1; i < threads; i++) {
    t[i] = (oc__loop_thread_t){&loop, i};
    ok[i] = pthread_create(&th[i], NULL, oc__loop_work, &t[i]) == 0;
  }
  oc__loop_work(&t[0]); /* the caller works too, and takes what failed starts leave */
  for (int i = 1; i < threads; i++)
    if (ok[i]) pthread_join(th[i], NULL);
}
