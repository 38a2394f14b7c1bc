/* ocp.h — the public header of proto/ (library oc_proto): wire frames and messages, epoch payloads
 * (the only user of zstd), the viewer's sans-IO session. Includes common's oc.h. */
#ifndef OCP_H
#define OCP_H

#include "oc.h"
#include "ocp_epoch.h"  /* epoch payloads: records and zstd-compressed bricks */
#include "ocp_viewer.h" /* the viewer's session, sans IO */
#include "ocp_wire.h"   /* frames and messages */

#endif /* OCP_H */
