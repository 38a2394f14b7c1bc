/* stress_verify.c — --verify-content: the tool checks the age of the content it receives by
 * itself. Viewers sample a fraction of the bricks they receive (stress_viewer.c) and queue them
 * here; one thread, at the lowest priority so that it takes as little as it can from the server and
 * the viewers it measures, re-produces each brick with a world of its own (server/world.h: the
 * server's scene, one thread, stepped clock, no viewers) at the stamps s, s − 1, s − 2, .. of the
 * brick's level before the state's world time (stress_stamp_scan) and counts the age of the first
 * that matches (stress_brick_matches), or none. A full queue drops samples (counted); what is left
 * at the end of a run or ramp phase is drained before the report. */
#define _GNU_SOURCE /* syscall(SYS_gettid): the nice value of this thread alone */
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include "oc.h"
#include "stress.h"

struct stress_verify_s {
  ocs_world_t *w;
  pthread_t thread;
  int started;
  pthread_mutex_t mu;
  pthread_cond_t cv;   /* work queued, or stop */
  pthread_cond_t idle; /* the queue emptied */
  stress_brick_sample_t *q;
  size_t cap, head, len;
  int busy, stop;
  double seconds;
  uint64_t reproduced;
};

static uint64_t sv__stamp(void *ctx, int level, double t) { return ocs_world_stamp_at(ctx, level, t); }

/* The age of one sample: 0..STRESS_AGE_MAX, STRESS_AGE_MAX + 1 when none matched, -1 on error. */
static int sv__age(stress_verify_t *v, const stress_brick_sample_t *s, double *seconds, uint64_t *made_n) {
  double times[STRESS_AGE_MAX + 1];
  uint64_t stamps[STRESS_AGE_MAX + 1];
  int level = oc_key_level(s->key);
  int n = stress_stamp_scan(sv__stamp, v->w, level, s->t, s->dt, STRESS_AGE_SCAN_EPOCHS, STRESS_AGE_MAX + 1, times, stamps);
  for (int k = 0; k < n; k++) {
    ocs_brick_out_t made;
    double t0 = stress_now();
    int r = ocs_world_reproduce(v->w, s->key, times[k], &made);
    *seconds += stress_now() - t0;
    (*made_n)++;
    if (r < 0) return -1;
    if (stress_brick_matches(s, &made)) return k;
  }
  return STRESS_AGE_MAX + 1;
}

static void *sv__main(void *arg) {
  stress_verify_t *v = arg;
  /* the lowest priority for this thread alone (Linux: nice is per thread) */
  (void)setpriority(PRIO_PROCESS, (id_t)syscall(SYS_gettid), 19);
  pthread_mutex_lock(&v->mu);
  for (;;) {
    while (!v->len && !v->stop) pthread_cond_wait(&v->cv, &v->mu);
    if (v->stop) break;
    stress_brick_sample_t s = v->q[v->head];
    v->head = (v->head + 1) % v->cap;
    v->len--;
    v->busy = 1;
    pthread_mutex_unlock(&v->mu);
    double sec = 0;
    uint64_t made = 0;
    int age = sv__age(v, &s, &sec, &made);
    pthread_mutex_lock(&v->mu);
    v->seconds += sec;
    v->reproduced += made;
    if (age < 0) s.into->errors++;
    else s.into->n[oc_key_level(s.key)][age]++;
    v->busy = 0;
    if (!v->len) pthread_cond_broadcast(&v->idle);
  }
  pthread_mutex_unlock(&v->mu);
  return NULL;
}

int stress_verify_start(stress_verify_t **out, const oc_scene_t *scene, size_t cap, char *why, size_t why_len) {
  *out = NULL;
  stress_verify_t *v = calloc(1, sizeof *v);
  if (!v || !(v->q = calloc(cap ? cap : 1, sizeof *v->q))) {
    free(v);
    return oc_errorf(OC_ENOMEM, why, why_len, "--verify-content: out of memory");
  }
  v->cap = cap ? cap : 1;
  ocs_world_desc_t d = {.threads = 1, .cache_bytes = 128ull << 20};
  char reason[512];
  int r = ocs_world_create(&v->w, scene, &d, reason, sizeof reason);
  if (r < 0) {
    free(v->q);
    free(v);
    return oc_errorf(r, why, why_len, "--verify-content: the verifier's world: %s", reason);
  }
  pthread_mutex_init(&v->mu, NULL);
  pthread_cond_init(&v->cv, NULL);
  pthread_cond_init(&v->idle, NULL);
  if (pthread_create(&v->thread, NULL, sv__main, v) != 0) {
    stress_verify_stop(v);
    return oc_errorf(OC_EIO, why, why_len, "--verify-content: cannot start a thread");
  }
  v->started = 1;
  *out = v;
  return 0;
}

void stress_verify_push(stress_verify_t *v, const stress_brick_sample_t *s) {
  pthread_mutex_lock(&v->mu);
  s->into->sampled++;
  if (v->len == v->cap) {
    s->into->dropped++;
  } else {
    v->q[(v->head + v->len) % v->cap] = *s;
    v->len++;
    pthread_cond_signal(&v->cv);
  }
  pthread_mutex_unlock(&v->mu);
}

size_t stress_verify_drain(stress_verify_t *v, double timeout_s) {
  if (!v) return 0;
  struct timespec until;
  clock_gettime(CLOCK_REALTIME, &until);
  double ns = (double)until.tv_nsec + timeout_s * 1e9;
  until.tv_sec += (time_t)(ns / 1e9);
  until.tv_nsec = (long)fmod(ns, 1e9);
  pthread_mutex_lock(&v->mu);
  while (v->len || v->busy)
    if (pthread_cond_timedwait(&v->idle, &v->mu, &until) == ETIMEDOUT) break;
  size_t left = v->len + (size_t)v->busy;
  pthread_mutex_unlock(&v->mu);
  return left;
}

void stress_verify_work(stress_verify_t *v, double *seconds, uint64_t *reproduced) {
  pthread_mutex_lock(&v->mu);
  *seconds = v->seconds;
  *reproduced = v->reproduced;
  pthread_mutex_unlock(&v->mu);
}

void stress_verify_stop(stress_verify_t *v) {
  if (!v) return;
  if (v->started) {
    pthread_mutex_lock(&v->mu);
    v->stop = 1;
    pthread_cond_broadcast(&v->cv);
    pthread_mutex_unlock(&v->mu);
    pthread_join(v->thread, NULL);
  }
  pthread_cond_destroy(&v->idle);
  pthread_cond_destroy(&v->cv);
  pthread_mutex_destroy(&v->mu);
  ocs_world_free(v->w);
  free(v->q);
  free(v);
}
