/* window.c - skyrender's X11 window through libxcb: frames tone-mapped on
 * the CPU and put as images; no swapchain, so it works on any X server
 * (Xvfb included) whatever Vulkan's surface support. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "window.h"

#ifdef SKYRENDER_XCB
#include <xcb/xcb.h>

#include "dump.h"

struct win {
	xcb_connection_t *conn;
	xcb_window_t window;
	xcb_gcontext_t gc;
	xcb_atom_t delete_atom;
	uint32_t width, height;
	uint8_t depth;
	uint32_t *pixels;		/* BGRX, the byte order of a little-endian 24-bit ZPixmap */
	bool closed;
};

static xcb_atom_t atom(xcb_connection_t *c, const char *name)
{
	xcb_intern_atom_reply_t *r = xcb_intern_atom_reply(c,
		xcb_intern_atom(c, 0, (uint16_t)strlen(name), name), NULL);
	xcb_atom_t a = r ? r->atom : XCB_ATOM_NONE;
	free(r);
	return a;
}

int win_new(uint32_t width, uint32_t height, const char *title, struct win **ret)
{
	if (!width || !height || !title || !ret)
		return -EINVAL;
	struct win *w = calloc(1, sizeof(*w));
	if (!w)
		return -ENOMEM;
	w->width = width;
	w->height = height;
	w->conn = xcb_connect(NULL, NULL);
	if (xcb_connection_has_error(w->conn)) {
		win_free(w);
		return -ENXIO;
	}
	xcb_screen_t *s = xcb_setup_roots_iterator(xcb_get_setup(w->conn)).data;
	const xcb_setup_t *setup = xcb_get_setup(w->conn);
	w->depth = s->root_depth;
	w->pixels = malloc((size_t)width * height * 4);
	if (!w->pixels || (s->root_depth != 24 && s->root_depth != 32) ||
	    setup->image_byte_order != XCB_IMAGE_ORDER_LSB_FIRST) {
		int rc = w->pixels ? -ENOTSUP : -ENOMEM;
		win_free(w);
		return rc;
	}
	w->window = xcb_generate_id(w->conn);
	uint32_t values[2] = { s->black_pixel, XCB_EVENT_MASK_KEY_PRESS | XCB_EVENT_MASK_EXPOSURE };
	xcb_create_window(w->conn, XCB_COPY_FROM_PARENT, w->window, s->root, 0, 0,
			  (uint16_t)width, (uint16_t)height, 0, XCB_WINDOW_CLASS_INPUT_OUTPUT,
			  s->root_visual, XCB_CW_BACK_PIXEL | XCB_CW_EVENT_MASK, values);
	xcb_change_property(w->conn, XCB_PROP_MODE_REPLACE, w->window, XCB_ATOM_WM_NAME,
			    XCB_ATOM_STRING, 8, (uint32_t)strlen(title), title);
	w->delete_atom = atom(w->conn, "WM_DELETE_WINDOW");
	xcb_atom_t protocols = atom(w->conn, "WM_PROTOCOLS");
	xcb_change_property(w->conn, XCB_PROP_MODE_REPLACE, w->window, protocols, XCB_ATOM_ATOM,
			    32, 1, &w->delete_atom);
	w->gc = xcb_generate_id(w->conn);
	xcb_create_gc(w->conn, w->gc, w->window, 0, NULL);
	xcb_map_window(w->conn, w->window);
	xcb_flush(w->conn);
	*ret = w;
	return 0;
}

void win_free(struct win *w)
{
	if (!w)
		return;
	if (w->conn)
		xcb_disconnect(w->conn);
	free(w->pixels);
	free(w);
}

int win_show(struct win *w, const float *rgba, double exposure)
{
	if (!w || !rgba || !(exposure > 0.0))
		return -EINVAL;
	if (w->closed || xcb_connection_has_error(w->conn))
		return -EIO;
	size_t n = (size_t)w->width * w->height;
	for (size_t i = 0; i < n; i++) {
		const float *p = rgba + 4 * i;
		w->pixels[i] = (uint32_t)dump_tonemap_srgb8(p[0], exposure, DUMP_CURVE_ACES) << 16 |
			       (uint32_t)dump_tonemap_srgb8(p[1], exposure, DUMP_CURVE_ACES) << 8 |
			       dump_tonemap_srgb8(p[2], exposure, DUMP_CURVE_ACES);
	}
	/* One request carries at most the server's maximum length: put the
	 * frame in bands of rows. */
	uint64_t max_bytes = (uint64_t)xcb_get_maximum_request_length(w->conn) * 4 - 64;
	uint32_t rows = (uint32_t)(max_bytes / ((uint64_t)w->width * 4));
	rows = rows < 1 ? 1 : rows;
	for (uint32_t y = 0; y < w->height; y += rows) {
		uint32_t h = w->height - y < rows ? w->height - y : rows;
		xcb_put_image(w->conn, XCB_IMAGE_FORMAT_Z_PIXMAP, w->window, w->gc,
			      (uint16_t)w->width, (uint16_t)h, 0, (int16_t)y, 0, w->depth,
			      w->width * h * 4, (const uint8_t *)(w->pixels + (size_t)y * w->width));
	}
	return xcb_flush(w->conn) > 0 ? 0 : -EIO;
}

int win_fd(const struct win *w)
{
	return w ? xcb_get_file_descriptor(w->conn) : -EINVAL;
}

bool win_closed(struct win *w)
{
	xcb_generic_event_t *ev;
	if (!w)
		return true;
	while ((ev = xcb_poll_for_event(w->conn))) {
		uint8_t type = ev->response_type & 0x7f;
		if (type == XCB_CLIENT_MESSAGE &&
		    ((xcb_client_message_event_t *)ev)->data.data32[0] == w->delete_atom)
			w->closed = true;
		/* keycode 9 is Escape and 24 is q on the usual evdev keymap */
		if (type == XCB_KEY_PRESS) {
			xcb_keycode_t k = ((xcb_key_press_event_t *)ev)->detail;
			w->closed |= k == 9 || k == 24;
		}
		free(ev);
	}
	return w->closed || xcb_connection_has_error(w->conn);
}

#else

int win_new(uint32_t width, uint32_t height, const char *title, struct win **ret)
{
	(void)width;
	(void)height;
	(void)title;
	(void)ret;
	return -ENOTSUP;
}

void win_free(struct win *w)
{
	(void)w;
}

int win_show(struct win *w, const float *rgba, double exposure)
{
	(void)w;
	(void)rgba;
	(void)exposure;
	return -ENOTSUP;
}

int win_fd(const struct win *w)
{
	(void)w;
	return -ENOTSUP;
}

bool win_closed(struct win *w)
{
	(void)w;
	return true;
}

#endif
