/* gl_window.c — GLFW window, OpenGL 4.5 core context and the fullscreen blit (gl_window.h). */
#include "gl_window.h"

#include <stdio.h>
#include <string.h>

#include "oc_err.h"

#ifdef OC_HAVE_GLFW

#include <epoxy/gl.h> /* before GLFW, which then includes no GL header of its own */
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <stdlib.h>

struct ocv_window_s {
  GLFWwindow *w;
  GLuint prog, vao;
  int fb_w, fb_h;
  int presses[OCV_ACT_COUNT];
  int looking;          /* left button held */
  double cx, cy;        /* cursor at the last event */
  double look_dx, look_dy;
};

/* GLFW reports errors through a callback; the last one is what ocv_window_open() explains. */
static char ocv__glfw_error[512];
static void ocv__on_error(int code, const char *text) {
  snprintf(ocv__glfw_error, sizeof ocv__glfw_error, "%s (GLFW error 0x%x)", text ? text : "?", (unsigned)code);
}

static void ocv__on_key(GLFWwindow *w, int key, int scancode, int action, int mods) {
  (void)scancode;
  (void)mods;
  ocv_window_t *win = glfwGetWindowUserPointer(w);
  if (action == GLFW_RELEASE) return;
  int a = -1;
  switch (key) {
    case GLFW_KEY_LEFT_BRACKET: a = OCV_ACT_STEP_MUL; break;
    case GLFW_KEY_RIGHT_BRACKET: a = OCV_ACT_STEP_DIV; break;
    case GLFW_KEY_MINUS: case GLFW_KEY_KP_SUBTRACT: a = OCV_ACT_EXPOSURE_DOWN; break;
    case GLFW_KEY_EQUAL: case GLFW_KEY_KP_ADD: a = OCV_ACT_EXPOSURE_UP; break;
    case GLFW_KEY_F12: case GLFW_KEY_P: if (action == GLFW_PRESS) a = OCV_ACT_SCREENSHOT; break;
    case GLFW_KEY_ESCAPE: if (action == GLFW_PRESS) a = OCV_ACT_QUIT; break;
    case GLFW_KEY_R: if (action == GLFW_PRESS) a = OCV_ACT_REPROJECT; break;
    case GLFW_KEY_V: if (action == GLFW_PRESS) a = OCV_ACT_DEBUG; break;
    case GLFW_KEY_H: if (action == GLFW_PRESS) a = OCV_ACT_HUD; break;
    case GLFW_KEY_J: if (action == GLFW_PRESS) a = OCV_ACT_JITTER; break;
    case GLFW_KEY_M: if (action == GLFW_PRESS) a = OCV_ACT_OCTAVES; break;
    case GLFW_KEY_N: if (action == GLFW_PRESS) a = OCV_ACT_WEATHER; break;
    case GLFW_KEY_K: a = OCV_ACT_SUN_WEST; break;
    case GLFW_KEY_L: a = OCV_ACT_SUN_EAST; break;
    case GLFW_KEY_T: if (action == GLFW_PRESS) a = OCV_ACT_TIME; break;
    default: break;
  }
  if (a >= 0) win->presses[a]++;
}

static void ocv__on_button(GLFWwindow *w, int button, int action, int mods) {
  (void)mods;
  ocv_window_t *win = glfwGetWindowUserPointer(w);
  if (button != GLFW_MOUSE_BUTTON_LEFT) return;
  win->looking = action == GLFW_PRESS;
  /* a hidden, captured cursor gives unbounded motion while looking around */
  glfwSetInputMode(w, GLFW_CURSOR, win->looking ? GLFW_CURSOR_DISABLED : GLFW_CURSOR_NORMAL);
  glfwGetCursorPos(w, &win->cx, &win->cy);
}

static void ocv__on_cursor(GLFWwindow *w, double x, double y) {
  ocv_window_t *win = glfwGetWindowUserPointer(w);
  if (win->looking) {
    win->look_dx += x - win->cx;
    win->look_dy += y - win->cy;
  }
  win->cx = x;
  win->cy = y;
}

static const char *ocv__vs =
    "#version 450 core\n"
    "out vec2 uv;\n"
    "void main() {\n"
    "  vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));\n" /* (0,0) (2,0) (0,2) */
    "  uv = vec2(p.x, 1.0 - p.y);\n" /* image rows run from the top */
    "  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);\n"
    "}\n";
static const char *ocv__fs =
    "#version 450 core\n"
    "layout(binding = 0) uniform sampler2D img;\n"
    "in vec2 uv;\n"
    "layout(location = 0) out vec4 color;\n"
    "void main() { color = vec4(texture(img, uv).rgb, 1.0); }\n";

static GLuint ocv__shader(GLenum type, const char *src, char *why, size_t wl) {
  GLuint s = glCreateShader(type);
  glShaderSource(s, 1, &src, NULL);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[512] = "";
    glGetShaderInfoLog(s, sizeof log, NULL, log);
    log[strcspn(log, "\n")] = '\0';
    (void)oc_errorf(0, why, wl, "window: blit shader: %s", log);
    glDeleteShader(s);
    return 0;
  }
  return s;
}

static int ocv__blit_program(ocv_window_t *win, char *why, size_t wl) {
  GLuint vs = ocv__shader(GL_VERTEX_SHADER, ocv__vs, why, wl);
  if (!vs) return -1;
  GLuint fs = ocv__shader(GL_FRAGMENT_SHADER, ocv__fs, why, wl);
  if (!fs) {
    glDeleteShader(vs);
    return -1;
  }
  win->prog = glCreateProgram();
  glAttachShader(win->prog, vs);
  glAttachShader(win->prog, fs);
  glLinkProgram(win->prog);
  glDeleteShader(vs);
  glDeleteShader(fs);
  GLint ok = 0;
  glGetProgramiv(win->prog, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[512] = "";
    glGetProgramInfoLog(win->prog, sizeof log, NULL, log);
    log[strcspn(log, "\n")] = '\0';
    (void)oc_errorf(0, why, wl, "window: blit program: %s", log);
    return -1;
  }
  glCreateVertexArrays(1, &win->vao); /* a core context draws nothing without one */
  return 0;
}

int ocv_window_available(void) { return 1; }

ocv_window_t *ocv_window_open(int w, int h, const char *title, char *why, size_t why_len) {
  ocv__glfw_error[0] = '\0';
  glfwSetErrorCallback(ocv__on_error);
  if (!glfwInit()) {
    (void)oc_errorf(0, why, why_len, "cannot open a window: %s", ocv__glfw_error[0] ? ocv__glfw_error : "glfwInit failed");
    return NULL;
  }
  ocv_window_t *win = calloc(1, sizeof *win);
  if (!win) {
    glfwTerminate();
    (void)oc_errorf(0, why, why_len, "out of memory");
    return NULL;
  }
  glfwWindowHint(GLFW_CLIENT_API, GLFW_OPENGL_API);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfwWindowHint(GLFW_DEPTH_BITS, 0);
  glfwWindowHint(GLFW_STENCIL_BITS, 0);
  win->w = glfwCreateWindow(w, h, title, NULL, NULL);
  if (!win->w) {
    (void)oc_errorf(0, why, why_len, "cannot make an OpenGL 4.5 core window: %s",
                    ocv__glfw_error[0] ? ocv__glfw_error : "glfwCreateWindow failed");
    free(win);
    glfwTerminate();
    return NULL;
  }
  glfwMakeContextCurrent(win->w);
  if (epoxy_gl_version() < 45) {
    (void)oc_errorf(0, why, why_len, "cannot make an OpenGL 4.5 core window: got OpenGL %d.%d",
                    epoxy_gl_version() / 10, epoxy_gl_version() % 10);
    ocv_window_close(win);
    return NULL;
  }
  glfwSetWindowUserPointer(win->w, win);
  glfwSetKeyCallback(win->w, ocv__on_key);
  glfwSetMouseButtonCallback(win->w, ocv__on_button);
  glfwSetCursorPosCallback(win->w, ocv__on_cursor);
  glfwSwapInterval(1);
  if (ocv__blit_program(win, why, why_len) < 0) {
    ocv_window_close(win);
    return NULL;
  }
  return win;
}

void ocv_window_close(ocv_window_t *win) {
  if (!win) return;
  if (win->w) {
    glfwMakeContextCurrent(win->w);
    if (win->vao) glDeleteVertexArrays(1, &win->vao);
    if (win->prog) glDeleteProgram(win->prog);
    glfwDestroyWindow(win->w);
  }
  free(win);
  glfwTerminate();
}

void ocv_window_poll(ocv_window_t *win, ocv_window_input_t *in) {
  glfwPollEvents();
  memset(in, 0, sizeof *in);
  static const int keys[OCV_KEY_COUNT][2] = {
      [OCV_KEY_FORWARD] = {GLFW_KEY_W, GLFW_KEY_UP},  [OCV_KEY_BACK] = {GLFW_KEY_S, GLFW_KEY_DOWN},
      [OCV_KEY_LEFT] = {GLFW_KEY_A, GLFW_KEY_LEFT},   [OCV_KEY_RIGHT] = {GLFW_KEY_D, GLFW_KEY_RIGHT},
      [OCV_KEY_DOWN] = {GLFW_KEY_Q, GLFW_KEY_Q},      [OCV_KEY_UP] = {GLFW_KEY_E, GLFW_KEY_E},
      [OCV_KEY_FAST] = {GLFW_KEY_LEFT_SHIFT, GLFW_KEY_RIGHT_SHIFT}};
  for (int k = 0; k < OCV_KEY_COUNT; k++)
    in->held[k] = glfwGetKey(win->w, keys[k][0]) == GLFW_PRESS || glfwGetKey(win->w, keys[k][1]) == GLFW_PRESS;
  memcpy(in->presses, win->presses, sizeof in->presses);
  memset(win->presses, 0, sizeof win->presses);
  in->look_dx = win->look_dx;
  in->look_dy = win->look_dy;
  win->look_dx = win->look_dy = 0;
  glfwGetFramebufferSize(win->w, &in->fb_w, &in->fb_h);
  in->resized = in->fb_w != win->fb_w || in->fb_h != win->fb_h;
  win->fb_w = in->fb_w;
  win->fb_h = in->fb_h;
  in->close = glfwWindowShouldClose(win->w) != 0;
  if (in->close) in->presses[OCV_ACT_QUIT]++;
}

void ocv_window_set_title(ocv_window_t *win, const char *title) { glfwSetWindowTitle(win->w, title); }

int ocv_window_present(ocv_window_t *win, unsigned int tex, char *why, size_t why_len) {
  int fw = 0, fh = 0;
  glfwGetFramebufferSize(win->w, &fw, &fh);
  glViewport(0, 0, fw, fh);
  glClearColor(0.1f, 0.1f, 0.1f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  if (tex && fw > 0 && fh > 0) {
    glUseProgram(win->prog);
    glBindVertexArray(win->vao);
    glBindTextureUnit(0, tex);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glBindVertexArray(0);
    glUseProgram(0);
  }
  glfwSwapBuffers(win->w);
  GLenum err = glGetError();
  if (err != GL_NO_ERROR) {
    (void)oc_errorf(0, why, why_len, "window: GL error 0x%x", (unsigned)err);
    return OC_EIO;
  }
  return 0;
}

#else /* no GLFW in this build: headless only */

struct ocv_window_s {
  int unused;
};

int ocv_window_available(void) { return 0; }

ocv_window_t *ocv_window_open(int w, int h, const char *title, char *why, size_t why_len) {
  (void)w;
  (void)h;
  (void)title;
  (void)oc_errorf(0, why, why_len, "cannot open a window: this build has no GLFW (use --headless)");
  return NULL;
}
void ocv_window_close(ocv_window_t *win) { (void)win; }
void ocv_window_poll(ocv_window_t *win, ocv_window_input_t *in) {
  (void)win;
  memset(in, 0, sizeof *in);
  in->close = 1;
}
void ocv_window_set_title(ocv_window_t *win, const char *title) {
  (void)win;
  (void)title;
}
int ocv_window_present(ocv_window_t *win, unsigned int tex, char *why, size_t why_len) {
  (void)win;
  (void)tex;
  (void)oc_errorf(0, why, why_len, "no window in this build");
  return OC_EIO;
}

#endif
