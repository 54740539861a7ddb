/* tests/test_foxglove_live.c -- the view's server speaking Foxglove's
 * WebSocket protocol, checked with an independent client:
 * @foxglove/ws-protocol's FoxgloveClient (npm registry, installed by
 * .ci/setup into the build folder; tests/tools/check_foxglove.cjs). A real
 * `isoshape run` with the live view; the client checks serverInfo, that the
 * advertised channels are the MCAP export's (iso_fox_channels of the same
 * session), that it receives the ticks in order with whole meshes, and
 * that a second client which subscribes and stops reading is disconnected
 * while the first keeps receiving new ticks. The run is then stopped with
 * SIGINT and must shut down cleanly (status 130). Without node or the
 * client the test skips with a reason. */
#include "testutil.h"

#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "iso_foxglove.h"
#include "iso_shapes.h"

#define SKIP_WHY(why)                                                                              \
    do {                                                                                           \
        print_message("SKIP: %s\n", why);                                                          \
        skip();                                                                                    \
    } while (0)

static const char scene_text[] = "name: fox\n"
                                 "mesh: {shape: cactus}\n"
                                 "regions:\n  sel: builtin\n  handles:\n    - name: top\n"
                                 "      driver: {screw: {def: builtin, duration: 120}}\n"
                                 "solver: {assembly: cpu, refactor: adaptive, worker_lag: 4}\n"
                                 "integrator: {abm: pec}\n"
                                 "tick_hz: 60\n"
                                 "sinks:\n  display: {port: 8080}\n";

/* Reads the child's stderr until the live view's port is said. */
static int read_port(FILE *f)
{
    char line[1024];
    while (fgets(line, sizeof line, f)) {
        const char *p = strstr(line, "live view on http://127.0.0.1:");
        if (p)
            return atoi(p + strlen("live view on http://127.0.0.1:"));
    }
    return -1;
}

static void foxglove_client_live(void **state)
{
    (void)state;
    char bin[1024];
    if (iso_test_isoshape_bin(bin, sizeof bin) != 0)
        SKIP_WHY("the isoshape binary is not built");
    if (system("node --version >/dev/null 2>&1") != 0)
        SKIP_WHY("node is not installed: no Foxglove client to connect with");
    struct stat st;
    if (stat(ISO_TEST_NODE_MODULES "/@foxglove/ws-protocol/package.json", &st) != 0 ||
        stat(ISO_TEST_NODE_MODULES "/ws/package.json", &st) != 0)
        SKIP_WHY("@foxglove/ws-protocol and ws are not installed in " ISO_TEST_NODE_MODULES
                 " (.ci/setup installs them from the npm registry)");
    char scene[512];
    snprintf(scene, sizeof scene, "%s/fox_live.yaml", ISO_TEST_TMP);
    FILE *sf = fopen(scene, "w");
    assert_non_null(sf);
    fputs(scene_text, sf);
    fclose(sf);
    /* the channels an MCAP export of this session has */
    iso_sink_session s;
    memset(&s, 0, sizeof s);
    iso_shape shape;
    iso_err e;
    assert_int_equal(iso_shape_init(&shape, "cactus", 0, &e), ISO_OK);
    s.n_handles = 1;
    snprintf(s.handle_name[0], sizeof s.handle_name[0], "top");
    iso_fox_channel ch[ISO_FOX_MAX_CHANNELS];
    int n_ch = iso_fox_channels(&s, ch, ISO_FOX_MAX_CHANNELS);
    int nt = shape.nt;
    iso_shape_deinit(&shape);

    int pipefd[2];
    assert_int_equal(pipe(pipefd), 0);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        dup2(pipefd[1], 2);
        close(pipefd[0]);
        freopen("/dev/null", "w", stdout);
        execl(bin, "isoshape", "run", scene, "--port", "0", "--no-rt", "--quiet", (char *)NULL);
        _exit(127);
    }
    close(pipefd[1]);
    FILE *err = fdopen(pipefd[0], "r");
    int port = read_port(err);
    if (port <= 0) {
        kill(pid, SIGKILL);
        waitpid(pid, NULL, 0);
        fail_msg("the run did not say its live view's port");
    }
    char cmd[4096];
    int n = snprintf(cmd, sizeof cmd, "node %s/tools/check_foxglove.cjs %s ws://127.0.0.1:%d/ws %d",
                     ISO_TEST_SOURCE_TESTS, ISO_TEST_NODE_MODULES, port, nt);
    for (int c = 0; c < n_ch; c++)
        n += snprintf(cmd + n, sizeof cmd - (size_t)n, " %s", ch[c].topic);
    static char out[16384], nerr[16384];
    int rc = iso_test_sh(cmd, out, sizeof out, nerr, sizeof nerr);
    print_message("%s%s", out, nerr);
    kill(pid, SIGINT);
    int status;
    waitpid(pid, &status, 0);
    fclose(err);
    assert_int_equal(rc, 0);
    assert_true(WIFEXITED(status));
    assert_int_equal(WEXITSTATUS(status), 130); /* stopped by SIGINT, shut down cleanly */
}

int main(void)
{
    const struct CMUnitTest t[] = {cmocka_unit_test(foxglove_client_live)};
    return cmocka_run_group_tests_name("foxglove_live", t, NULL, NULL);
}
