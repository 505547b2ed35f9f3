/* sdfq.c - the command line of sdfd for people and shell scripts (docs/sdfq.md): finds the
 * subcommand, parses its options (args.c), works out the server's HTTP URL and binary
 * address from options and environment, and runs it (commands.c; bake.c, which also has
 * ops; slice.c; mesh.c). Queries use the binary protocol through libsdfclient; the rest use the
 * HTTP API through libcurl. */
#include <curl/curl.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "commands.h"

#define GLOBAL_HELP                                                                          \
    "Options of every subcommand:\n"                                                         \
    "  --server URL     sdfd's HTTP API (env SDFD_URL; default http://127.0.0.1:8080)\n"     \
    "  --bin HOST:PORT  its binary protocol (env SDFD_BIN; default the --server host, 9090)\n" \
    "  --token T        its bearer token (env SDFD_TOKEN)\n"                                 \
    "  --bin-tls        the binary port speaks TLS, as sdfd --bin-tls (env SDFD_BIN_TLS=1)\n"  \
    "  --cacert FILE    CA certificates (PEM) to verify an https:// or --bin-tls server\n"     \
    "                   against (env SDFD_CACERT; default the system's)\n"                     \
    "  --timeout S      seconds to wait for an answer (default 120)\n"                       \
    "Exit: 0 ok, 1 usage, 2 the server refused (its status and code on stderr), 3 cannot\n"  \
    "connect or the connection failed, 4 bad input file, 5 cannot write the output.\n"

typedef struct command {
    const char *name;
    int (*run)(const sdfq_server *, const sdfq_args *);
    const char *options; /* space-separated; a trailing ':' takes a value */
    const char *help;
} command;

static const command commands[] = {
    {"query", sdfq_cmd_query,
     "mode: sign: o: output-format: batch: samples: seed: kernel: cap:",
     "usage: sdfq query MESH [POINTS.npy|POINTS.csv|-] [options]\n"
     "Distances of points (N x 3; .npy float32/float64 or CSV x,y,z; default stdin) to MESH,\n"
     "over the binary protocol, as CSV (default) or npy.\n"
     "  --mode M            signed (default), distance, gradient, closest, filtered,\n"
     "                      filtered-gradient\n"
     "  --sign S            auto (default), pseudonormal, winding, raycast, none\n"
     "  -o OUT              OUT.npy, OUT.csv or - (stdout, the default)\n"
     "  --output-format F   npy or csv, whatever OUT's name says\n"
     "  --batch N           points per request (default 65536; requests are pipelined)\n"
     "  --samples N --seed S --kernel gaussian|bump --cap F   the filtered modes' parameters\n"},
    {"query-volume", sdfq_cmd_query_volume, "gradient interpolation: o: output-format: batch:",
     "usage: sdfq query-volume VOLUME [POINTS.npy|POINTS.csv|-] [options]\n"
     "Evaluate a baked volume at points over the binary protocol.\n"
     "  --gradient          value and gradient (4 columns) instead of the value\n"
     "  --interpolation I   default (hermite on first-order volumes, trilinear on\n"
     "                      zero-order ones), trilinear, nearest or hermite\n"
     "  -o OUT, --output-format F, --batch N   as in sdfq query\n"},
    {"meshes", sdfq_cmd_meshes, "",
     "usage: sdfq meshes\n"
     "The loaded meshes, one a line: name, triangles, closed|open, the sign auto picks\n"
     "(tab-separated; binary protocol).\n"},
    {"upload", sdfq_cmd_upload, "format:",
     "usage: sdfq upload NAME FILE [--format obj|ply|stl|off]\n"
     "Load a mesh file as NAME (replacing one of that name); prints the server's report.\n"},
    {"bake", sdfq_cmd_bake,
     "volume: resolution: order: margin: encoding: sign: normalize: wait op+ solver: "
     "iterations: band: strict",
     "usage: sdfq bake MESH [--volume NAME] [--resolution N] [--order 0|1] [--op OP]... [--wait]\n"
     "Bake MESH into a distance volume (docs/volumes.md). Without --wait prints the job id;\n"
     "with it, shows progress on stderr (a bar on a terminal, a line a tenth otherwise) and\n"
     "prints the finished job's JSON.\n"
     "  --volume NAME       store it as NAME (default: the mesh's name)\n"
     "  --resolution N      nodes per axis, 2..4096 (server default 64)\n"
     "  --order 0|1         zero or first order (server default 0)\n"
     "  --margin F --encoding float32|packed32 --sign S --normalize plane|gradient\n"
     "  --op OP             a field operation on the baked grid before it is stored, as in\n"
     "                      sdfq ops (repeat it for a chain, applied in order); with\n"
     "                      --solver, --iterations, --band, --strict as there\n"},
    {"ops", sdfq_cmd_ops, "volume: solver: iterations: band: strict wait",
     "usage: sdfq ops VOLUME OP... [--volume OUT] [--solver sussman|sweep|exact] [--wait]\n"
     "Field operations on VOLUME (docs/api.md, Field operations), applied in order, each\n"
     "round=R (convex edges), fillet=R (concave ones), smooth=R (both), offset=R (the\n"
     "surface moves outward by R, inward for R < 0) or redistance=R (exact up to R; 0: the\n"
     "whole grid). Without --wait prints the job id; with it, shows progress as sdfq bake\n"
     "does and prints the finished job's JSON (its caveats; a warning also on stderr).\n"
     "  --volume OUT        store the result as OUT (default: replace VOLUME)\n"
     "  --solver S          sweep (server default), sussman or exact\n"
     "  --iterations N      per re-distancing, 0..1000000 (server default 0: derived)\n"
     "  --band B            the distance up to which the result is exact (0: 4 cells)\n"
     "  --strict            a caveat fails the job\n"},
    {"download", sdfq_cmd_download, "o: format:",
     "usage: sdfq download VOLUME -o FILE [--format exr|npy|raw]\n"
     "Save a volume (-o - writes it to stdout). The format defaults from FILE's extension\n"
     "(.npy, .raw, else exr).\n"},
    {"slice", sdfq_cmd_slice,
     "o: volume format: axis: at: normal: origin: bounds: size: mode: sign: interpolation: "
     "step: samples: seed: kernel: cap:",
     "usage: sdfq slice NAME -o FILE [--volume] [--axis x|y|z] [--at F] [options]\n"
     "Save a slice of mesh NAME (or, with --volume, of the volume NAME) as a PNG picture, or\n"
     "its values as a float32 (H, W) npy file (docs/api.md, Slices; -o - writes to stdout).\n"
     "  --format png|npy    default from FILE's extension (.npy, else png)\n"
     "  --axis, --at        the plane across x, y or z (default z) at a coordinate\n"
     "  --normal nx,ny,nz --origin x,y,z   any plane instead\n"
     "  --bounds x0,y0,z0,x1,y1,z1 --size N (pixels of the longer side, default 512)\n"
     "  --mode signed|distance|filtered|gradient|error --sign S --interpolation I --step F\n"
     "  --samples N --seed S --kernel gaussian|bump --cap F   mode filtered's parameters\n"},
    {"mesh", sdfq_cmd_mesh, "o: mesh: format: iso: cap",
     "usage: sdfq mesh VOLUME -o FILE [--format ply|obj|stl|off] [--iso F] [--cap]\n"
     "       sdfq mesh VOLUME --mesh NEW [--iso F] [--cap]\n"
     "The surface of VOLUME's values (docs/api.md, Meshes from volumes), closed and manifold\n"
     "where it stays inside the grid: saved as a mesh file (-o - writes it to stdout), or\n"
     "stored on the server as the mesh NEW (its report printed).\n"
     "  --format F          ply (binary), obj, stl (binary) or off; default from FILE's\n"
     "                      extension, else ply\n"
     "  --iso F             the value whose surface is taken (default 0)\n"
     "  --cap               close it where it leaves the grid (caps on its boundary)\n"},
    {"delete", sdfq_cmd_delete, "volume job",
     "usage: sdfq delete [--volume|--job] NAME...\n"
     "Delete meshes (default), volumes or jobs (a running job is canceled).\n"},
    {"volumes", sdfq_cmd_volumes, "",
     "usage: sdfq volumes\n"
     "The stored volumes, one a line: name, dims, order, encoding, bytes (tab-separated).\n"},
};

static const char *const global_options = "server: bin: bin-tls cacert: token: timeout: help";

static void usage(FILE *f)
{
    fprintf(f, "usage: sdfq COMMAND [options] [arguments]   (sdfq COMMAND --help; sdfq --version)\n"
               "Commands:\n");
    for (size_t i = 0; i < sizeof commands / sizeof *commands; i++)
        fprintf(f, "  %s\n", commands[i].help + strlen("usage: sdfq "));
    fputs(GLOBAL_HELP, f);
}

/* Turn "a: b c: d+" plus the global options into an option table (':' takes a value, '+' a
 * value that may be given again). */
static int make_options(const char *spec, sdfq_opt *opts, char *storage, size_t cap)
{
    snprintf(storage, cap, "%s %s", spec, global_options);
    int n = 0;
    for (char *save, *tok = strtok_r(storage, " ", &save); tok; tok = strtok_r(NULL, " ", &save)) {
        size_t len = strlen(tok);
        int value = tok[len - 1] == ':' ? 1 : tok[len - 1] == '+' ? 2 : 0;
        if (value)
            tok[len - 1] = 0;
        opts[n++] = (sdfq_opt){.name = tok, .takes_value = value};
    }
    return n;
}

/* --bin HOST:PORT, "[v6]:PORT" too; 0 or SDFQ_USAGE. */
static int parse_bin(const char *s, sdfq_server *srv)
{
    const char *colon = strrchr(s, ':');
    char *end;
    long port = colon ? strtol(colon + 1, &end, 10) : 0;
    size_t hl = colon ? (size_t)(colon - s) : 0;
    if (hl >= 2 && s[0] == '[' && s[hl - 1] == ']')
        s++, hl -= 2;
    if (!colon || hl == 0 || hl >= sizeof srv->bin_host || *end || port < 1 || port > 65535) {
        fprintf(stderr, "sdfq: --bin must be HOST:PORT, not '%s'\n", s);
        return SDFQ_USAGE;
    }
    memcpy(srv->bin_host, s, hl);
    srv->bin_host[hl] = 0;
    srv->bin_port = (int)port;
    return 0;
}

/* The binary address's default: the HTTP URL's host, port 9090. */
static int bin_from_url(sdfq_server *srv)
{
    CURLU *u = curl_url();
    char *host = NULL;
    int ok = u && !curl_url_set(u, CURLUPART_URL, srv->url, 0) &&
             !curl_url_get(u, CURLUPART_HOST, &host, 0);
    if (ok) {
        size_t n = strlen(host);
        if (n >= 2 && host[0] == '[')
            snprintf(srv->bin_host, sizeof srv->bin_host, "%.*s", (int)(n - 2), host + 1);
        else
            snprintf(srv->bin_host, sizeof srv->bin_host, "%s", host);
        srv->bin_port = 9090;
    } else {
        fprintf(stderr, "sdfq: --server must be a URL such as http://127.0.0.1:8080, not '%s'\n",
                srv->url);
    }
    curl_free(host);
    curl_url_cleanup(u);
    return ok ? 0 : SDFQ_USAGE;
}

/* --cacert and --bin-tls, and their environment variables (SDFD_BIN_TLS as sdfd reads it:
 * 1, true, 0, false). */
static int configure_tls(const sdfq_args *a, sdfq_server *srv)
{
    const char *env;
    srv->cacert = sdfq_opt_value(a, "cacert");
    if (!srv->cacert && (env = getenv("SDFD_CACERT")) && *env)
        srv->cacert = env;
    if (srv->cacert && access(srv->cacert, R_OK)) {
        fprintf(stderr, "sdfq: cannot read the CA file %s: %s\n", srv->cacert, strerror(errno));
        return SDFQ_INPUT;
    }
    srv->bin_tls = sdfq_opt_value(a, "bin-tls") != NULL;
    if (!srv->bin_tls && (env = getenv("SDFD_BIN_TLS")) && *env) {
        srv->bin_tls = !strcmp(env, "1") || !strcmp(env, "true");
        if (!srv->bin_tls && strcmp(env, "0") && strcmp(env, "false")) {
            fprintf(stderr, "sdfq: SDFD_BIN_TLS must be 1, true, 0 or false, not '%s'\n", env);
            return SDFQ_USAGE;
        }
    }
    return 0;
}

static int configure(const sdfq_args *a, sdfq_server *srv)
{
    const char *env;
    srv->url = sdfq_opt_value(a, "server");
    if (!srv->url)
        srv->url = (env = getenv("SDFD_URL")) && *env ? env : "http://127.0.0.1:8080";
    srv->token = sdfq_opt_value(a, "token");
    if (!srv->token && (env = getenv("SDFD_TOKEN")) && *env)
        srv->token = env;
    double timeout = 120;
    if (sdfq_opt_double(a, "timeout", &timeout) || timeout <= 0 || timeout > 86400) {
        fprintf(stderr, "sdfq: --timeout must be seconds in (0, 86400]\n");
        return SDFQ_USAGE;
    }
    srv->timeout_ms = (int)(timeout * 1000);
    const char *bin = sdfq_opt_value(a, "bin");
    if (!bin && (env = getenv("SDFD_BIN")) && *env)
        bin = env;
    int rc = configure_tls(a, srv);
    return rc ? rc : bin ? parse_bin(bin, srv) : bin_from_url(srv);
}

/* The subcommand's index in argv: the first argument that is neither a global option nor
 * its value (global options may come before it); 0 if none. */
static int find_command(int argc, char **argv)
{
    static const char *const valued[] = {"--server", "--bin", "--token", "--timeout", "--cacert"};
    for (int i = 1; i < argc; i++) {
        int skip = 0;
        for (size_t k = 0; k < sizeof valued / sizeof *valued; k++)
            skip |= !strcmp(argv[i], valued[k]);
        if (skip)
            i++;
        else if (argv[i][0] != '-')
            return i;
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 2 && !strcmp(argv[1], "--version")) {
        printf("sdfq %s\n", SDFD_VERSION);
        return SDFQ_OK;
    }
    int at = find_command(argc, argv);
    if (!at) {
        int help = argc > 1 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h"));
        usage(help ? stdout : stderr);
        return help ? SDFQ_OK : SDFQ_USAGE;
    }
    const command *cmd = NULL;
    for (size_t i = 0; i < sizeof commands / sizeof *commands; i++)
        if (!strcmp(argv[at], commands[i].name))
            cmd = &commands[i];
    if (!strcmp(argv[at], "help")) {
        usage(stdout);
        return SDFQ_OK;
    }
    if (!cmd) {
        fprintf(stderr, "sdfq: unknown command '%s' (see sdfq --help)\n", argv[at]);
        return SDFQ_USAGE;
    }
    /* the arguments around the command's name, in their order */
    char **rest = malloc(sizeof *rest * (size_t)argc);
    if (!rest)
        return SDFQ_USAGE;
    int nrest = 0;
    for (int i = 1; i < argc; i++)
        if (i != at)
            rest[nrest++] = argv[i];
    sdfq_opt opts[32];
    char storage[512];
    int n = make_options(cmd->options, opts, storage, sizeof storage);
    sdfq_args a;
    int rc = sdfq_parse(&a, cmd->name, opts, n, nrest, rest);
    if (!rc && sdfq_opt_value(&a, "help")) {
        fputs(cmd->help, stdout);
        fputs(GLOBAL_HELP, stdout);
    } else if (!rc) {
        sdfq_server srv = {0};
        rc = configure(&a, &srv);
        if (!rc) {
            curl_global_init(CURL_GLOBAL_DEFAULT);
            rc = cmd->run(&srv, &a);
            curl_global_cleanup();
        }
    } else {
        rc = SDFQ_USAGE;
    }
    free(rest);
    return rc;
}
