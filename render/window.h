/* window.h - skyrender's optional window: an X11 window (libxcb) that shows
 * each frame with the PNG files' encoding (dump_png's exposure, curve and
 * sRGB). Built only where libxcb was found; elsewhere win_new() says so. */
#ifndef SKYRENDER_WINDOW_H
#define SKYRENDER_WINDOW_H

#include <stdbool.h>
#include <stdint.h>

struct win;

/* Opens a width x height window on $DISPLAY. -ENOTSUP when built without
 * libxcb or when the screen is not 24-bit true colour, -ENXIO without a
 * display. The caller frees *ret with win_free(). */
int win_new(uint32_t width, uint32_t height, const char *title, struct win **ret);
void win_free(struct win *w);

/* Shows a frame: width * height RGBA floats, linear, rows top to bottom,
 * scaled by exposure (> 0) before the curve. 0 or -EIO (the display went). */
int win_show(struct win *w, const float *rgba, double exposure);

/* The connection's fd, for poll (POLLIN: events to read with win_closed). */
int win_fd(const struct win *w);

/* Reads the window's events; true once it was closed (the window manager's
 * close, Escape or q) or the display went away. */
bool win_closed(struct win *w);

#endif
