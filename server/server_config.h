/* server_config.h — the options of overcast-server: one table (server_config.c, as Redis's
 * static_configs[]) that parses the command line into an ocs_config_t and generates --help.
 *
 * Each row names an option, its type, its destination in ocs_config_t, its default (the
 * OCS_CONFIG_DEFAULT_* macros below), its inclusive range, a help text and its group ("Serving
 * (the default mode)", "Other modes", "Any mode"). The serving rows fill `desc`, which goes to
 * ocs_server_create() as it is; the other modes' values are the fields after it. */
#ifndef OC_SERVER_SERVER_CONFIG_H
#define OC_SERVER_SERVER_CONFIG_H

#include <stdint.h>

#include "oc_camera.h"
#include "ocs_server.h"

/* Defaults of the options (--help prints them from the table). A serving default equals what
 * ocs_server_create() and the world read 0 as. */
#define OCS_CONFIG_DEFAULT_HOST "127.0.0.1"
#define OCS_CONFIG_DEFAULT_PORT 7420
#define OCS_CONFIG_DEFAULT_MAX_VIEWERS 64
#define OCS_CONFIG_DEFAULT_TOTAL_BUDGET 4096 /* MiB */
#define OCS_CONFIG_DEFAULT_CACHE 256         /* MiB */
#define OCS_CONFIG_DEFAULT_LINGER 30         /* s */
#define OCS_CONFIG_DEFAULT_DRAIN 30          /* s */
#define OCS_CONFIG_DEFAULT_MAX_LINGERING 16
#define OCS_CONFIG_DEFAULT_MAX_PER_ADDRESS 32
#define OCS_CONFIG_DEFAULT_HANDSHAKE_RATE 10 /* connections per second from one address */
#define OCS_CONFIG_DEFAULT_IDLE_TIMEOUT 60   /* s */
#define OCS_CONFIG_DEFAULT_STALL_TIMEOUT 30  /* s */
#define OCS_CONFIG_DEFAULT_QUEUE_SOFT 4      /* MiB */
#define OCS_CONFIG_DEFAULT_QUEUE_HARD 16     /* MiB */
#define OCS_CONFIG_DEFAULT_ZSTD_LEVEL 3      /* OCP_LEVEL_DEFAULT */
#define OCS_CONFIG_DEFAULT_RADIUS 5000       /* m, --region */
#define OCS_CONFIG_DEFAULT_LEVEL 16
#define OCS_CONFIG_DEFAULT_TIME 0            /* s */
#define OCS_CONFIG_DEFAULT_EPOCHS 8
#define OCS_CONFIG_DEFAULT_BUDGET 64         /* MiB, --save-state */
#define OCS_CONFIG_DEFAULT_VIEWPORT_W 1280
#define OCS_CONFIG_DEFAULT_VIEWPORT_H 720

/* ocs_config_parse()'s return when the command line is good and a mode is to run. */
#define OCS_CONFIG_RUN (-1)

typedef struct {
  ocs_server_desc_t desc;    /**< serving; desc.host points into `host` */
  char host[64];             /**< --listen's address */
  const char *listen;        /**< --listen as given, or the default */
  char metrics_host[64];     /**< --metrics-listen's address */
  char redis_host[64];       /**< --redis's address */
  const char *metrics_listen; /**< --metrics-listen as given; NULL: no metrics */
  const char *scene_path;    /**< NULL: the built-in procedural planet */
  int check, json, quiet;
  const char *inspect, *export_path, *save_path;
  double region[4];          /**< --region: lat, lon, alt, radius */
  int region_given;          /**< 0: the region is centred on the scene camera */
  int level, epochs, threads;
  double time;
  oc_camera_pose_t camera;
  int camera_given;          /**< 0: the scene's camera */
  uint64_t budget;           /**< --save-state's viewer budget, bytes */
  int viewport[2];
  int serving;               /**< the mode: no --check, --export-vdb, --save-state or --inspect */
} ocs_config_t;

/*! ocs_config_parse() : parses argv with the table, prints --help / --version, and applies the
 *  cross-option checks (--json goes with --inspect, serving options go without the other modes,
 *  a non-loopback --listen needs --token or --insecure, ...). @return OCS_CONFIG_RUN, or the exit
 *  status to return (OC_EXIT_OK after --help or --version, OC_EXIT_USAGE after a one-line error). */
int ocs_config_parse(ocs_config_t *cfg, int argc, char **argv);

/*! ocs_config_is_loopback() : whether a numeric address is a loopback one (127.0.0.0/8, ::1, or
 *  ::ffff:127.0.0.0/104); NULL is the default host, 127.0.0.1. @return 1: loopback; 0: another IPv4
 *  or IPv6 address; -1: not a numeric address (binding it fails anyway). */
int ocs_config_is_loopback(const char *host);

#endif /* OC_SERVER_SERVER_CONFIG_H */
