/* main.c - skyd's entry point. The daemon's loop comes with the control
 * server; until then the offline modes are what skyd does. */
#include "once.h"

int main(int argc, char **argv)
{
	return once_main(argc, argv);
}
