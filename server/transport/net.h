/* net.h - listening sockets for both front ends (net.c). */
#ifndef SDFD_NET_H
#define SDFD_NET_H

/* Open a listening TCP socket on "HOST:PORT"; returns the fd (and the bound port in *port)
 * or -1 after logging why. */
int sdfd_listen(const char *addr, int *port);

#endif
