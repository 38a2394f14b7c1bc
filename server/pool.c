/* pool.c — see pool.h. */
#define _GNU_SOURCE /* gettid() */
#include "pool.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <unistd.h>

#include "oc_err.h"

struct ocs_pool_s {
  int threads;
  int spawned0; /* index of the first spawned worker: 1 (the caller is worker 0) or 0 */
  int nice;
  pthread_t tid[OCS_POOL_MAX_THREADS];
  pthread_mutex_t mu;
  pthread_cond_t go, done;
  uint64_t generation; /* bumped per run; workers wait for a new one */
  int busy;            /* workers still inside the current run */
  int quit;
  /* the current run */
  ocs_pool_fn fn;
  void *ctx;
  size_t n;
  atomic_size_t next;
  atomic_int err;
};

static void run_share(ocs_pool_t *p, int worker) {
  for (;;) {
    size_t i = atomic_fetch_add(&p->next, 1);
    if (i >= p->n) return;
    int r = p->fn(p->ctx, i, worker);
    if (r < 0) {
      int z = 0;
      atomic_compare_exchange_strong(&p->err, &z, r);
    }
  }
}

typedef struct {
  ocs_pool_t *p;
  int worker;
} arg_t;

static void *worker_main(void *a) {
  arg_t arg = *(arg_t *)a;
  free(a);
  ocs_pool_t *p = arg.p;
  uint64_t seen = 0;
  if (p->nice > 0) setpriority(PRIO_PROCESS, (id_t)gettid(), p->nice); /* per thread on Linux; best effort */
  pthread_mutex_lock(&p->mu);
  for (;;) {
    while (!p->quit && p->generation == seen) pthread_cond_wait(&p->go, &p->mu);
    if (p->quit) break;
    seen = p->generation;
    pthread_mutex_unlock(&p->mu);
    run_share(p, arg.worker);
    pthread_mutex_lock(&p->mu);
    if (--p->busy == 0) pthread_cond_signal(&p->done);
  }
  pthread_mutex_unlock(&p->mu);
  return NULL;
}

int ocs_pool_create(ocs_pool_t **out, int threads) { return ocs_pool_create_niced(out, threads, 0); }

int ocs_pool_create_niced(ocs_pool_t **out, int threads, int nice) {
  if (!out || threads < 0 || nice < 0 || nice > 19) return OC_EINVAL;
  *out = NULL;
  if (threads == 0) {
    long c = sysconf(_SC_NPROCESSORS_ONLN);
    threads = c > 0 ? (int)c : 1;
  }
  if (threads > OCS_POOL_MAX_THREADS) threads = OCS_POOL_MAX_THREADS;
  ocs_pool_t *p = calloc(1, sizeof *p);
  if (!p) return OC_ENOMEM;
  pthread_mutex_init(&p->mu, NULL);
  pthread_cond_init(&p->go, NULL);
  pthread_cond_init(&p->done, NULL);
  p->nice = nice;
  p->spawned0 = p->threads = nice > 0 ? 0 : 1;
  for (int i = p->spawned0; i < threads; i++) {
    arg_t *a = malloc(sizeof *a);
    if (!a) break;
    *a = (arg_t){p, i};
    if (pthread_create(&p->tid[i], NULL, worker_main, a) != 0) {
      free(a);
      break;
    }
    p->threads++;
  }
  *out = p;
  return 0;
}

void ocs_pool_free(ocs_pool_t *p) {
  if (!p) return;
  pthread_mutex_lock(&p->mu);
  p->quit = 1;
  pthread_cond_broadcast(&p->go);
  pthread_mutex_unlock(&p->mu);
  for (int i = p->spawned0; i < p->threads; i++) pthread_join(p->tid[i], NULL);
  pthread_mutex_destroy(&p->mu);
  pthread_cond_destroy(&p->go);
  pthread_cond_destroy(&p->done);
  free(p);
}

int ocs_pool_threads(const ocs_pool_t *p) { return !p ? 0 : p->threads > 0 ? p->threads : 1; }

int ocs_pool_run(ocs_pool_t *p, size_t n, ocs_pool_fn fn, void *ctx) {
  if (!p || !fn) return OC_EINVAL;
  if (n == 0) return 0;
  pthread_mutex_lock(&p->mu);
  p->fn = fn;
  p->ctx = ctx;
  p->n = n;
  atomic_store(&p->next, 0);
  atomic_store(&p->err, 0);
  p->busy = p->threads - p->spawned0;
  p->generation++;
  pthread_cond_broadcast(&p->go);
  pthread_mutex_unlock(&p->mu);
  if (p->spawned0 || !p->threads) run_share(p, 0); /* no worker could be spawned: the caller works */
  pthread_mutex_lock(&p->mu);
  while (p->busy > 0) pthread_cond_wait(&p->done, &p->mu);
  pthread_mutex_unlock(&p->mu);
  return atomic_load(&p->err);
}
