/* commands.h - sdfq's subcommands. Each takes the arguments after its name and the server
 * to talk to, prints its result on stdout and any failure as one line on stderr, and
 * returns an exit code of sdfq.h. Help texts are in sdfq.c. */
#ifndef SDFQ_COMMANDS_H
#define SDFQ_COMMANDS_H

#include "args.h"
#include "sdfq.h"

/* Binary protocol (libsdfclient). */
int sdfq_cmd_query(const sdfq_server *srv, const sdfq_args *a);
int sdfq_cmd_query_volume(const sdfq_server *srv, const sdfq_args *a);
int sdfq_cmd_meshes(const sdfq_server *srv, const sdfq_args *a);
/* HTTP (libcurl). */
int sdfq_cmd_upload(const sdfq_server *srv, const sdfq_args *a);
int sdfq_cmd_download(const sdfq_server *srv, const sdfq_args *a);
int sdfq_cmd_delete(const sdfq_server *srv, const sdfq_args *a);
int sdfq_cmd_volumes(const sdfq_server *srv, const sdfq_args *a);
int sdfq_cmd_bake(const sdfq_server *srv, const sdfq_args *a); /* bake.c */
int sdfq_cmd_ops(const sdfq_server *srv, const sdfq_args *a);  /* bake.c */
int sdfq_cmd_slice(const sdfq_server *srv, const sdfq_args *a); /* slice.c */
int sdfq_cmd_mesh(const sdfq_server *srv, const sdfq_args *a);  /* mesh.c */

#endif
