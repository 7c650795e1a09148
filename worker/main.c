/* main.c: photonfarm-worker, a render-farm worker process. Parses the
 * command line, turns SIGINT/SIGTERM into a stop flag, and runs the worker
 * loop (worker/loop.h) until it ends. Exit codes: 0 normal end (signal, or
 * BYE with --exit-on-bye), 1 fatal error (a key file unreadable, malformed
 * or readable by others), 2 usage, 3 refused by the coordinator with
 * --exit-on-bye (without it a refused worker keeps trying). */
#include <errno.h>
#include <getopt.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/log.h"
#include "proto/messages.h"
#include "worker/loop.h"

static volatile sig_atomic_t s_stop;

static void s_on_signal(int sig)
{
    (void)sig;
    s_stop = 1;
}

static void s_usage(FILE *f)
{
    fprintf(f,
            "photonfarm-worker %s (%s, protocol %d): renders tiles for a photonfarm coordinator\n"
            "\n"
            "usage:\n"
            "  photonfarm-worker --connect ENDPOINT [options]\n"
            "  photonfarm-worker --help | --version\n"
            "\n"
            "options:\n"
            "  -c, --connect ENDPOINT        the coordinator, e.g. tcp://host:7878 or ipc:///tmp/pf.sock\n"
            "  -t, --threads N               rendering threads (0: all cores)\n"
            "  -n, --name NAME               name in logs and on the coordinator (default: host:pid)\n"
            "      --curve-key FILE          this worker's CURVE key pair (photonfarm keygen)\n"
            "      --curve-server-key FILE   the coordinator's CURVE public key\n"
            "      --peer-port N             serve the blobs this worker holds to other workers on TCP\n"
            "                                port N (0, the default: any free port; loopback only when\n"
            "                                the coordinator is local; off with CURVE, and with an\n"
            "                                ipc:// coordinator unless N is given)\n"
            "      --no-peers                serve no other worker\n"
            "      --exit-on-bye             exit when the coordinator says goodbye, or is gone once\n"
            "                                served (default: wait for the next one)\n"
            "  -q, --quiet                   only errors\n"
            "  -v, --verbose                 debug logging\n"
            "      --fake-protocol N         (tests) announce protocol version N in HELLO, to see\n"
            "                                the coordinator refuse it\n"
            "\n"
            "The worker keeps serving coordinators, one job after another, until SIGINT or SIGTERM.\n"
            "A refused worker (another protocol version, a CURVE key not on the coordinator's list)\n"
            "tries again with a backoff doubling to 300 s, so it gets in once the coordinator admits it.\n"
            "Exit codes: 0 normal end, 1 fatal error (e.g. a key file unreadable, or readable by others),\n"
            "2 usage error, 3 refused by the coordinator with --exit-on-bye.\n",
            PF_VERSION, PF_GIT_HASH, PF_PROTO_VERSION);
}

static int s_usage_error(const char *fmt, const char *arg)
{
    fprintf(stderr, "photonfarm-worker: ");
    fprintf(stderr, fmt, arg);
    fprintf(stderr, "\n(see photonfarm-worker --help)\n");
    return PF_WORKER_EXIT_USAGE;
}

int main(int argc, char **argv)
{
    enum { OPT_CURVE_KEY = 256, OPT_CURVE_SERVER_KEY, OPT_EXIT_ON_BYE, OPT_VERSION, OPT_FAKE_PROTOCOL, OPT_PEER_PORT, OPT_NO_PEERS };
    static const struct option longopts[] = {
        { "connect", required_argument, NULL, 'c' },
        { "threads", required_argument, NULL, 't' },
        { "name", required_argument, NULL, 'n' },
        { "curve-key", required_argument, NULL, OPT_CURVE_KEY },
        { "curve-server-key", required_argument, NULL, OPT_CURVE_SERVER_KEY },
        { "exit-on-bye", no_argument, NULL, OPT_EXIT_ON_BYE },
        { "quiet", no_argument, NULL, 'q' },
        { "verbose", no_argument, NULL, 'v' },
        { "help", no_argument, NULL, 'h' },
        { "version", no_argument, NULL, OPT_VERSION },
        { "fake-protocol", required_argument, NULL, OPT_FAKE_PROTOCOL },
        { "peer-port", required_argument, NULL, OPT_PEER_PORT },
        { "no-peers", no_argument, NULL, OPT_NO_PEERS },
        { NULL, 0, NULL, 0 },
    };
    pf_worker_opts_t o;
    memset(&o, 0, sizeof o);
    pf_log_level level = PF_LOG_INFO;
    opterr = 0;
    int c;
    while ((c = getopt_long(argc, argv, ":c:t:n:qvh", longopts, NULL)) != -1) {
        switch (c) {
        case 'c': o.endpoint = optarg; break;
        case 't': {
            char *end;
            errno = 0;
            long v = strtol(optarg, &end, 10);
            if (errno || end == optarg || *end || v < 0 || v > 4096)
                return s_usage_error("--threads wants a number from 0 to 4096, not '%s'", optarg);
            o.threads = (int)v;
            break;
        }
        case 'n':
            if (!optarg[0] || strlen(optarg) > 200)
                return s_usage_error("--name wants 1 to 200 characters%s", "");
            o.name = optarg;
            break;
        case OPT_CURVE_KEY: o.curve_key = optarg; break;
        case OPT_CURVE_SERVER_KEY: o.curve_server_key = optarg; break;
        case OPT_EXIT_ON_BYE: o.exit_on_bye = 1; break;
        case OPT_NO_PEERS: o.peer_port = -1; break;
        case OPT_PEER_PORT: {
            char *end;
            errno = 0;
            long v = strtol(optarg, &end, 10);
            if (errno || end == optarg || *end || v < 0 || v > 65535)
                return s_usage_error("--peer-port wants a number from 0 to 65535, not '%s'", optarg);
            o.peer_port = (int)v;
            break;
        }
        case OPT_FAKE_PROTOCOL: {
            char *end;
            errno = 0;
            long v = strtol(optarg, &end, 10);
            if (errno || end == optarg || *end || v < 1 || v > 65535)
                return s_usage_error("--fake-protocol wants a number from 1 to 65535, not '%s'", optarg);
            o.fake_protocol = (int)v;
            break;
        }
        case 'q': level = PF_LOG_ERROR; break;
        case 'v': level = PF_LOG_DEBUG; break;
        case 'h': s_usage(stdout); return 0;
        case OPT_VERSION:
            printf("photonfarm-worker %s (%s, protocol %d)\n", PF_VERSION, PF_GIT_HASH, PF_PROTO_VERSION);
            return 0;
        case ':': return s_usage_error("%s needs a value", argv[optind - 1]);
        default: return s_usage_error("unknown option '%s'", argv[optind - 1]);
        }
    }
    if (optind < argc)
        return s_usage_error("unexpected argument '%s'", argv[optind]);
    if (!o.endpoint)
        return s_usage_error("--connect ENDPOINT is required%s", "");
    if (!o.curve_key != !o.curve_server_key)
        return s_usage_error("CURVE needs both --curve-key and --curve-server-key%s", "");
    pf_log_set_level(level);

    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = s_on_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0; /* no SA_RESTART: zmq_poll returns at once with EINTR */
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);

    o.stop = &s_stop;
    return pf_worker_run(&o);
}
