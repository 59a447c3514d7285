/* sensor_mcp2221.c - the MCP2221A family: Microchip's USB to I2C bridge
 * (04d8:00dd) with a ROHM BH1750 ambient light sensor on its bus.
 *
 * The bridge (datasheet DS20005565) speaks in 64-byte reports on its HID
 * interface's interrupt endpoints: each command (OUT) gets one response
 * (IN) echoing the command code, byte 1 0 on success. 0x10 reads the status
 * and sets parameters (byte 2 0x10 cancels the I2C transfer in progress,
 * byte 3 0x20 sets the I2C clock divider of byte 4, 12 MHz / rate - 3;
 * the response's byte 3 says 0x20 when the rate was taken, byte 8 is the
 * I2C engine's state, byte 20 bit 6 a NACK of the address). 0x90 writes
 * bytes 4.. to the I2C address in byte 3 (8-bit form), length in bytes 1-2.
 * 0x91 reads that many bytes into the bridge; 0x40 then fetches them: byte 1
 * 0 (0x41: failed), byte 2 the engine's state (0x55: read complete), byte 3
 * the count (127: error), the data from byte 4.
 *
 * The BH1750 (I2C 0x23, or 0x5c with ADDR high): 0x01 powers it on, 0x10
 * measures continuously at high resolution; 01000_MT[7:5] and 011_MT[4:0]
 * set the measurement time register (31..254, default 69); a reading is
 * two bytes, big-endian, lux = count / 1.2 * 69 / MT. skyd sets MT = 31:
 * the range reaches 121.6 klx (direct sunlight) at 2.2 lx a count and a
 * measurement takes at most 81 ms. */
#include "sensor_internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#define MCP_VENDOR 0x04d8
#define MCP_PRODUCT 0x00dd
#define MCP_REPORT 64
#define MCP_STATUS 0x10
#define MCP_STATUS_CANCEL 0x10		/* byte 2 */
#define MCP_STATUS_SET_SPEED 0x20	/* byte 3, and the response's byte 3 when taken */
#define MCP_I2C_WRITE 0x90
#define MCP_I2C_READ 0x91
#define MCP_I2C_GET 0x40
#define MCP_I2C_READ_COMPLETE 0x55
#define MCP_I2C_GET_ERROR 127
#define MCP_ADDR_NACK 0x40		/* status byte 20 */
#define MCP_I2C_HZ 100000
#define MCP_CLOCK_HZ 12000000
/* The bridge needs the I2C transfer a command started to finish before
 * the next command: at 100 kHz three bytes take well under 1 ms. */
#define MCP_STEP_NS 2000000ull
#define MCP_GET_RETRIES 3

#define BH1750_ADDR_LOW 0x23
#define BH1750_ADDR_HIGH 0x5c
#define BH1750_POWER_ON 0x01
#define BH1750_CONTINUOUS_HIGH_RES 0x10
#define BH1750_MT_HIGH 0x40
#define BH1750_MT_LOW 0x60
#define BH1750_MT 31
#define BH1750_MT_DEFAULT 69
#define BH1750_COUNTS_PER_LUX 1.2
#define BH1750_MEASURE_MAX_S 0.081	/* 180 ms at MT 69, scaled to 31 */

typedef void (*mcp_answer_fn)(struct sensor_dev *d, const uint8_t *resp);

struct mcp_priv {
	uint8_t ep_in, ep_out;
	uint8_t cmd[MCP_REPORT];
	mcp_answer_fn answer;
	uint8_t addr;			/* the BH1750's 7-bit address */
	int addr_index;
	int config_step;
	int get_tries;
	int reading;			/* 1 once the sensor is set up */
};

static const uint8_t bh1750_addrs[] = { BH1750_ADDR_LOW, BH1750_ADDR_HIGH };

static int mcp_match(const struct libusb_device_descriptor *dd,
		     const struct libusb_config_descriptor *cfg)
{
	if (dd->idVendor != MCP_VENDOR || dd->idProduct != MCP_PRODUCT)
		return -1;
	for (int i = 0; i < cfg->bNumInterfaces; i++)
		if (cfg->interface[i].num_altsetting > 0 &&
		    cfg->interface[i].altsetting[0].bInterfaceClass == LIBUSB_CLASS_HID)
			return cfg->interface[i].altsetting[0].bInterfaceNumber;
	return -1;
}

static void poll_sensor(struct sensor_dev *d);

/* A failed exchange while reading costs one reading and the bus is
 * cancelled; during set-up the device gives up (and is retried). */
static void exchange_failed(struct sensor_dev *d, const char *what)
{
	struct mcp_priv *p = sensor_dev_priv(d);

	if (!p->reading) {
		sensor_dev_fail(d, 0, "MCP2221A set-up: %s", what);
		return;
	}
	sensor_dev_note(d, "%s", what);
	sensor_dev_reading(d, NAN, SENSOR_REJECT_MALFORMED);
	sensor_dev_timer(d, (uint64_t)(sensor_dev_config(d)->report_interval_s * 1e9), poll_sensor);
}

/* The response: it must echo the command code. */
static void in_done(struct sensor_dev *d, int status, const uint8_t *data, size_t len)
{
	struct mcp_priv *p = sensor_dev_priv(d);
	char what[80];

	if (status < 0) {
		snprintf(what, sizeof(what), "response to 0x%02x: %s", p->cmd[0], strerror(-status));
		exchange_failed(d, what);
		return;
	}
	if (len < 24 || data[0] != p->cmd[0]) {
		snprintf(what, sizeof(what), "response of %zu bytes to 0x%02x starts 0x%02x", len,
			 p->cmd[0], len ? data[0] : 0);
		exchange_failed(d, what);
		return;
	}
	p->answer(d, data);
}

static void out_done(struct sensor_dev *d, int status, const uint8_t *data, size_t len)
{
	struct mcp_priv *p = sensor_dev_priv(d);
	char what[80];
	int r;

	if (status < 0) {
		snprintf(what, sizeof(what), "command 0x%02x: %s", p->cmd[0], strerror(-status));
		exchange_failed(d, what);
		return;
	}
	r = sensor_dev_interrupt(d, p->ep_in, NULL, MCP_REPORT, 0, in_done);
	if (r < 0 && r != -ESHUTDOWN)
		sensor_dev_fail(d, 0, "reading a response: %s", strerror(-r));
}

/* One command and its response; answer gets the response. */
static void exchange(struct sensor_dev *d, const uint8_t *cmd, size_t len, mcp_answer_fn answer)
{
	struct mcp_priv *p = sensor_dev_priv(d);
	int r;

	memset(p->cmd, 0, sizeof(p->cmd));
	memcpy(p->cmd, cmd, len);
	p->answer = answer;
	r = sensor_dev_interrupt(d, p->ep_out, p->cmd, MCP_REPORT, 0, out_done);
	if (r < 0 && r != -ESHUTDOWN)
		sensor_dev_fail(d, 0, "sending a command: %s", strerror(-r));
}

static void i2c_write(struct sensor_dev *d, uint8_t byte, mcp_answer_fn answer)
{
	struct mcp_priv *p = sensor_dev_priv(d);
	uint8_t cmd[5] = { MCP_I2C_WRITE, 1, 0, (uint8_t)(p->addr << 1), byte };

	exchange(d, cmd, sizeof(cmd), answer);
}

static void cancel_answered(struct sensor_dev *d, const uint8_t *resp)
{
}

static void cancel_i2c(struct sensor_dev *d, mcp_answer_fn answer)
{
	uint8_t cmd[3] = { MCP_STATUS, 0, MCP_STATUS_CANCEL };

	exchange(d, cmd, sizeof(cmd), answer ? answer : cancel_answered);
}

/* ---- reading ---- */

static void schedule_poll(struct sensor_dev *d)
{
	double s = fmax(sensor_dev_config(d)->report_interval_s, BH1750_MEASURE_MAX_S);

	sensor_dev_timer(d, (uint64_t)(s * 1e9), poll_sensor);
}

static void get_data(struct sensor_dev *d);

/* 0x40's answer: the two bytes of the BH1750, or why not; a read not yet
 * complete is fetched again shortly. */
static void got_data(struct sensor_dev *d, const uint8_t *resp)
{
	struct mcp_priv *p = sensor_dev_priv(d);

	if (resp[1] != 0 || resp[3] == MCP_I2C_GET_ERROR) {
		sensor_dev_note(d, "I2C read from 0x%02x failed (0x%02x 0x%02x)", p->addr, resp[1],
				resp[3]);
		sensor_dev_reading(d, NAN, SENSOR_REJECT_MALFORMED);
		cancel_i2c(d, NULL);
		schedule_poll(d);
		return;
	}
	if (resp[2] != MCP_I2C_READ_COMPLETE && ++p->get_tries < MCP_GET_RETRIES) {
		sensor_dev_timer(d, MCP_STEP_NS, get_data);
		return;
	}
	if (resp[2] != MCP_I2C_READ_COMPLETE || resp[3] != 2) {
		sensor_dev_note(d, "I2C read gave %u bytes in state 0x%02x", resp[3], resp[2]);
		sensor_dev_reading(d, NAN, SENSOR_REJECT_MALFORMED);
	} else {
		unsigned count = (unsigned)resp[4] << 8 | resp[5];
		double lux = count / BH1750_COUNTS_PER_LUX * BH1750_MT_DEFAULT / BH1750_MT;
		sensor_dev_reading(d, lux, count == 0xffff ? SENSOR_REJECT_SATURATED
							   : SENSOR_REJECT_NONE);
	}
	schedule_poll(d);
}

static void get_data(struct sensor_dev *d)
{
	uint8_t cmd[1] = { MCP_I2C_GET };

	exchange(d, cmd, sizeof(cmd), got_data);
}

static void read_started(struct sensor_dev *d, const uint8_t *resp)
{
	struct mcp_priv *p = sensor_dev_priv(d);

	if (resp[1] != 0) {
		sensor_dev_note(d, "I2C read not started (engine busy): cancelled");
		cancel_i2c(d, NULL);
		schedule_poll(d);
		return;
	}
	p->get_tries = 0;
	sensor_dev_timer(d, MCP_STEP_NS, get_data);
}

static void poll_sensor(struct sensor_dev *d)
{
	struct mcp_priv *p = sensor_dev_priv(d);
	uint8_t cmd[4] = { MCP_I2C_READ, 2, 0, (uint8_t)(p->addr << 1 | 1) };

	exchange(d, cmd, sizeof(cmd), read_started);
}

/* ---- set-up: I2C rate, find the BH1750, configure it ---- */

static void configure_next(struct sensor_dev *d);

static void configured(struct sensor_dev *d, const uint8_t *resp)
{
	struct mcp_priv *p = sensor_dev_priv(d);

	if (resp[1] != 0) {
		sensor_dev_fail(d, 0, "BH1750 set-up write refused (0x%02x)", resp[1]);
		return;
	}
	p->config_step++;
	sensor_dev_timer(d, MCP_STEP_NS, configure_next);
}

static void configure_next(struct sensor_dev *d)
{
	struct mcp_priv *p = sensor_dev_priv(d);
	static const uint8_t steps[] = { BH1750_MT_HIGH | (BH1750_MT >> 5),
					 BH1750_MT_LOW | (BH1750_MT & 0x1f),
					 BH1750_CONTINUOUS_HIGH_RES };

	if (p->config_step < (int)sizeof(steps)) {
		i2c_write(d, steps[p->config_step], configured);
		return;
	}
	p->reading = 1;
	sensor_dev_ready(d, "BH1750 at 0x%02x, MT %d, %.3f lx a count", p->addr, BH1750_MT,
			 BH1750_MT_DEFAULT / (BH1750_COUNTS_PER_LUX * BH1750_MT));
	schedule_poll(d);
}

static void probe_address(struct sensor_dev *d);

static void next_address(struct sensor_dev *d, const uint8_t *resp)
{
	struct mcp_priv *p = sensor_dev_priv(d);

	if (++p->addr_index >= (int)sizeof(bh1750_addrs)) {
		sensor_dev_fail(d, 1, "no BH1750 answers at 0x%02x or 0x%02x", BH1750_ADDR_LOW,
				BH1750_ADDR_HIGH);
		return;
	}
	sensor_dev_timer(d, MCP_STEP_NS, probe_address);
}

/* After the power-on write: anything but a clean idle engine without an
 * address NACK means nothing answers there. */
static void probe_status(struct sensor_dev *d, const uint8_t *resp)
{
	struct mcp_priv *p = sensor_dev_priv(d);

	if (resp[1] != 0 || (resp[20] & MCP_ADDR_NACK) || resp[8] != 0) {
		cancel_i2c(d, next_address);
		return;
	}
	p->config_step = 0;
	sensor_dev_timer(d, MCP_STEP_NS, configure_next);
}

static void probe_check(struct sensor_dev *d)
{
	uint8_t cmd[1] = { MCP_STATUS };

	exchange(d, cmd, sizeof(cmd), probe_status);
}

static void probe_written(struct sensor_dev *d, const uint8_t *resp)
{
	if (resp[1] != 0) {
		cancel_i2c(d, next_address);
		return;
	}
	sensor_dev_timer(d, MCP_STEP_NS, probe_check);
}

/* Powers the sensor on at the next candidate address; the status after
 * it says whether anything acknowledged. */
static void probe_address(struct sensor_dev *d)
{
	struct mcp_priv *p = sensor_dev_priv(d);

	p->addr = bh1750_addrs[p->addr_index];
	i2c_write(d, BH1750_POWER_ON, probe_written);
}

static void speed_set(struct sensor_dev *d, const uint8_t *resp)
{
	if (resp[1] != 0) {
		sensor_dev_fail(d, 0, "status command refused (0x%02x)", resp[1]);
		return;
	}
	if (resp[3] != MCP_STATUS_SET_SPEED)
		sensor_dev_note(d, "I2C rate not taken (bus busy); probing at the current rate");
	sensor_dev_timer(d, MCP_STEP_NS, probe_address);
}

/* The HID interface's two interrupt endpoints, then the I2C rate. */
static int mcp_start(struct sensor_dev *d)
{
	struct mcp_priv *p = sensor_dev_priv(d);
	struct libusb_config_descriptor *cfg;
	uint8_t cmd[5] = { MCP_STATUS, 0, 0, MCP_STATUS_SET_SPEED,
			   (uint8_t)(MCP_CLOCK_HZ / MCP_I2C_HZ - 3) };

	if (libusb_get_active_config_descriptor(sensor_dev_usb(d), &cfg) < 0)
		return -EIO;
	for (int i = 0; i < cfg->bNumInterfaces; i++) {
		const struct libusb_interface_descriptor *alt = &cfg->interface[i].altsetting[0];
		if (cfg->interface[i].num_altsetting < 1 ||
		    alt->bInterfaceNumber != sensor_dev_interface(d))
			continue;
		for (int e = 0; e < alt->bNumEndpoints; e++) {
			const struct libusb_endpoint_descriptor *ep = &alt->endpoint[e];
			if ((ep->bmAttributes & 3) != LIBUSB_TRANSFER_TYPE_INTERRUPT)
				continue;
			if (ep->bEndpointAddress & LIBUSB_ENDPOINT_IN)
				p->ep_in = ep->bEndpointAddress;
			else
				p->ep_out = ep->bEndpointAddress;
		}
	}
	libusb_free_config_descriptor(cfg);
	if (!p->ep_in || !p->ep_out)
		return -ENOENT;
	exchange(d, cmd, sizeof(cmd), speed_set);
	return 0;
}

const struct sensor_driver sensor_mcp2221_driver = {
	.family = "mcp2221-bh1750",
	.match = mcp_match,
	.precheck = NULL,
	.priv_size = sizeof(struct mcp_priv),
	.start = mcp_start,
	.stop = NULL,
};
