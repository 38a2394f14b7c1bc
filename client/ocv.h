/* ocv.h — the public header of client/ (library oc_client, and oc_gl when built with GL): the
 * connection and its network thread (net.h), overcast-server as a child process (child.h), camera
 * paths (camera_path.h), interpolation between states (interp.h), the HUD (hud.h) and, with
 * OC_HAVE_GL, the GL renderer (gl/ocv_gl.h). Includes proto's ocp.h; never anything of server/. */
#ifndef OCV_H
#define OCV_H

#include "ocp.h"
#include "camera_path.h" /* recorded camera paths */
#include "child.h"       /* overcast-server as a child process */
#include "hud.h"         /* the HUD */
#include "interp.h"      /* interpolation between states */
#include "net.h"         /* the connection, ocv_fetch, the network thread */
#ifdef OC_HAVE_GL
#include "ocv_gl.h" /* the GL renderer */
#endif

#endif /* OCV_H */
