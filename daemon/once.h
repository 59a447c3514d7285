/* once.h - skyd's offline modes, run instead of the daemon. */
#ifndef SKYD_ONCE_H
#define SKYD_ONCE_H

/* Handles `skyd --list-devices` and `skyd --once [--dump DIR] [--device SEL]
 * [key=value ...]`. Returns the process exit status: 0 done, 1 device or
 * file failure, 2 bad input (a message naming the key and the rule). */
int once_main(int argc, char **argv);

#endif
