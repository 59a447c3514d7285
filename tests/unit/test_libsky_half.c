/* test_libsky_half.c - skysample.h's binary16 decoding: normals,
 * subnormals, signed zero, infinities, NaN, and every integer a half holds
 * exactly up to 2047. */
#include <math.h>

#include "fake_skyd.h"
#include "sky.h"
#include "skysample.h"
#include "test.h"

static void test_half(void)
{
	CHECK_EQ(skysample_half(0x3c00), 1.0);
	CHECK_EQ(skysample_half(0xc000), -2.0);
	CHECK_EQ(skysample_half(0x3800), 0.5);
	CHECK_EQ(skysample_half(0x7bff), 65504.0);
	CHECK_EQ(skysample_half(0x0001), ldexp(1.0, -24));
	CHECK_EQ(skysample_half(0x03ff), ldexp(1023.0, -24));
	CHECK_EQ(skysample_half(0x0400), ldexp(1.0, -14));
	CHECK_EQ(skysample_half(0x3555), 1365.0 / 4096.0);
	CHECK(skysample_half(0x8000) == 0.0 && signbit(skysample_half(0x8000)));
	CHECK(isinf(skysample_half(0x7c00)) && skysample_half(0x7c00) > 0);
	CHECK(isinf(skysample_half(0xfc00)) && skysample_half(0xfc00) < 0);
	CHECK(isnan(skysample_half(0x7e00)));
	for (int i = 1; i < 2048; i++)
		CHECK_EQ(skysample_half(fake_skyd_half(i)), i);
}

int main(void)
{
	test_half();
	return test_report("test_libsky_half");
}
