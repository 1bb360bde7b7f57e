/* millac_plugin.c - QEMU TCG plugin for the millac virtual logic analyser (host).
 *
 * Supported QEMU: 7.x (TCG plugin API version 1; tested with Debian's 7.2). QEMU 8.0+ changed the API
 * (version 2+, QEMU 10 is version 4) and refuses this build: the declarations below are a hand-written
 * subset of QEMU 7.2's include/qemu/qemu-plugin.h because Debian ships no header.
 *
 * What it records (under -icount shift=N,sleep=off, virtual time = count << N ns):
 *  - every executed instruction adds 1 to a 64-bit counter (inline add, no call);
 *  - every store whose address lies in [base, base+0x1000) of a watched GPIO port:  "s COUNT ADDR" (hex);
 *  - per interrupt handler k, from executing its entry instruction to executing one of its exit
 *    (return) instructions, inclusive, and the count of its entry instruction (instruction k of
 *    the run has count k, as in the store records):                              "h K INSNS START"
 *    (hex). A handler preempted by another counts the preempting instructions too.
 *  - with trace=K, over=N: the PCs of every call of handler K longer than N instructions, in the
 *    order executed (at most MAX_TRACE):                          "t K START PC PC PC ..." (hex).
 *    Every instruction then gets an execution callback: a run is slower, the counts the same.
 * Last line written at exit: "e COUNT" (total instructions, hex).
 *
 * Arguments (QEMU 7.2 form: -plugin lib.so,key=value,key=value ...):
 *   out=PATH        output file (required)
 *   gpio=0xADDR     watched 4 KiB GPIO block base, repeatable (max 16)
 *   hK_entry=0xPC   entry PC of handler K (K = 0..15, Thumb bit cleared)
 *   hK_exit=0xPC    a return-instruction PC of handler K, repeatable
 *   trace=K         trace handler K's long calls (see above; needs over=)
 *   over=N          the length (instructions) a call must exceed to be traced
 * Output is written through a buffered FILE and flushed by the plugin atexit callback; QEMU 7.2 exits
 * through exit() on semihosting SYS_EXIT, which runs it (measured). A write that fails (a full disk)
 * is said at exit on stderr, "millac_plugin: cannot write PATH: REASON", so the host does not
 * take a cut log for a whole one.
 */
#include <errno.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define QEMU_PLUGIN_EXPORT __attribute__((visibility("default")))
typedef uint64_t qemu_plugin_id_t;
typedef struct qemu_info_t qemu_info_t; /* only passed by pointer here */
struct qemu_plugin_tb;
struct qemu_plugin_insn;
typedef uint32_t qemu_plugin_meminfo_t;
enum qemu_plugin_cb_flags { QEMU_PLUGIN_CB_NO_REGS, QEMU_PLUGIN_CB_R_REGS, QEMU_PLUGIN_CB_RW_REGS };
enum qemu_plugin_mem_rw { QEMU_PLUGIN_MEM_R = 1, QEMU_PLUGIN_MEM_W, QEMU_PLUGIN_MEM_RW };
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 };
typedef void (*qemu_plugin_udata_cb_t)(qemu_plugin_id_t id, void *userdata);
typedef void (*qemu_plugin_vcpu_udata_cb_t)(unsigned int vcpu_index, void *userdata);
typedef void (*qemu_plugin_vcpu_tb_trans_cb_t)(qemu_plugin_id_t id, struct qemu_plugin_tb *tb);
typedef void (*qemu_plugin_vcpu_mem_cb_t)(unsigned int vcpu_index, qemu_plugin_meminfo_t info,
                                          uint64_t vaddr, void *userdata);
void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t id, qemu_plugin_vcpu_tb_trans_cb_t cb);
void qemu_plugin_register_vcpu_insn_exec_cb(struct qemu_plugin_insn *insn, qemu_plugin_vcpu_udata_cb_t cb,
                                            enum qemu_plugin_cb_flags flags, void *userdata);
void qemu_plugin_register_vcpu_insn_exec_inline(struct qemu_plugin_insn *insn, enum qemu_plugin_op op,
                                                void *ptr, uint64_t imm);
void qemu_plugin_register_vcpu_mem_cb(struct qemu_plugin_insn *insn, qemu_plugin_vcpu_mem_cb_t cb,
                                      enum qemu_plugin_cb_flags flags, enum qemu_plugin_mem_rw rw,
                                      void *userdata);
void qemu_plugin_register_atexit_cb(qemu_plugin_id_t id, qemu_plugin_udata_cb_t cb, void *userdata);
size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *tb, size_t idx);
uint64_t qemu_plugin_insn_vaddr(const struct qemu_plugin_insn *insn);
bool qemu_plugin_mem_is_store(qemu_plugin_meminfo_t info);

QEMU_PLUGIN_EXPORT int qemu_plugin_version = 1;

#define MAX_PORTS 16
#define MAX_H 16
#define MAX_EXITS 16
#define MAX_TRACE 1024

static FILE *out;
static char out_path[4096];
static int write_errno; /* the first failed write's errno, 0: none */

/* Notes the first failed write of the log. */
static void check(int r)
{
    if (r < 0 && !write_errno)
        write_errno = errno ? errno : EIO;
}
static uint64_t count; /* single vCPU (Cortex-M3) */
static uint64_t ports[MAX_PORTS];
static int n_ports;
static struct handler {
    uint64_t entry;
    uint64_t exits[MAX_EXITS];
    int n_exits;
    bool has_entry, active;
    uint64_t start;
} hs[MAX_H];
static int trace_k = -1;
static uint64_t trace_over;
static uint64_t trace_pcs[MAX_TRACE];
static size_t trace_n;

static void on_store(unsigned int vcpu, qemu_plugin_meminfo_t info, uint64_t vaddr, void *ud)
{
    (void)vcpu; (void)ud;
    /* QEMU 7.2 also calls QEMU_PLUGIN_MEM_W callbacks for loads (measured): filter here. */
    if (!qemu_plugin_mem_is_store(info))
        return;
    for (int i = 0; i < n_ports; i++) {
        if (vaddr >= ports[i] && vaddr < ports[i] + 0x1000) {
            check(fprintf(out, "s %llx %llx\n", (unsigned long long)count, (unsigned long long)vaddr));
            return;
        }
    }
}

static void on_entry(unsigned int vcpu, void *ud)
{
    struct handler *h = ud;
    (void)vcpu;
    h->active = true;
    h->start = count;
    if (h - hs == trace_k) {
        trace_pcs[0] = h->entry;
        trace_n = 1;
    }
}

static void on_traced_insn(unsigned int vcpu, void *ud)
{
    (void)vcpu;
    if (hs[trace_k].active && trace_n < MAX_TRACE)
        trace_pcs[trace_n++] = (uint64_t)(uintptr_t)ud;
}

static void on_exit_insn(unsigned int vcpu, void *ud)
{
    struct handler *h = ud;
    (void)vcpu;
    if (h->active) {
        uint64_t n = count - h->start + 1;
        h->active = false;
        /* An execution callback runs before its instruction's inline add (measured on 7.2): the
         * entry instruction's own count, as a store's, is start + 1. */
        check(fprintf(out, "h %x %llx %llx\n", (unsigned)(h - hs), (unsigned long long)n,
                      (unsigned long long)(h->start + 1)));
        if (h - hs == trace_k && n > trace_over) {
            check(fprintf(out, "t %x %llx", (unsigned)(h - hs), (unsigned long long)(h->start + 1)));
            for (size_t i = 0; i < trace_n; i++)
                check(fprintf(out, " %llx", (unsigned long long)trace_pcs[i]));
            check(fputc('\n', out) == EOF ? -1 : 0);
        }
    }
}

static void on_tb_trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    (void)id;
    size_t n = qemu_plugin_tb_n_insns(tb);
    for (size_t i = 0; i < n; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        uint64_t pc = qemu_plugin_insn_vaddr(insn);
        qemu_plugin_register_vcpu_insn_exec_inline(insn, QEMU_PLUGIN_INLINE_ADD_U64, &count, 1);
        qemu_plugin_register_vcpu_mem_cb(insn, on_store, QEMU_PLUGIN_CB_NO_REGS, QEMU_PLUGIN_MEM_W, NULL);
        /* Registered before the handlers' callbacks (QEMU calls them in that order): the entry
         * callback records the entry PC itself, and the exit PC is recorded before the exit
         * callback writes the trace, so a trace holds all INSNS PCs. */
        if (trace_k >= 0)
            qemu_plugin_register_vcpu_insn_exec_cb(insn, on_traced_insn, QEMU_PLUGIN_CB_NO_REGS,
                                                   (void *)(uintptr_t)pc);
        for (int k = 0; k < MAX_H; k++) {
            if (hs[k].has_entry && hs[k].entry == pc)
                qemu_plugin_register_vcpu_insn_exec_cb(insn, on_entry, QEMU_PLUGIN_CB_NO_REGS, &hs[k]);
            for (int j = 0; j < hs[k].n_exits; j++)
                if (hs[k].exits[j] == pc)
                    qemu_plugin_register_vcpu_insn_exec_cb(insn, on_exit_insn, QEMU_PLUGIN_CB_NO_REGS, &hs[k]);
        }
    }
}

static void on_atexit(qemu_plugin_id_t id, void *ud)
{
    (void)id; (void)ud;
    if (out) {
        check(fprintf(out, "e %llx\n", (unsigned long long)count));
        check(fflush(out) == 0 ? 0 : -1);
        check(fclose(out) == 0 ? 0 : -1);
        out = NULL;
        if (write_errno)
            fprintf(stderr, "millac_plugin: cannot write %s: %s\n", out_path, strerror(write_errno));
    }
}

static int parse_u64(const char *s, uint64_t *v)
{
    char *end;
    *v = strtoull(s, &end, 0);
    return (*s && !*end) ? 0 : -1;
}

QEMU_PLUGIN_EXPORT int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info, int argc,
                                           char **argv)
{
    const char *path = NULL;
    (void)info;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        const char *eq = strchr(a, '=');
        uint64_t v;
        int k, off = 0;
        if (!eq) goto bad;
        if (!strncmp(a, "out=", 4)) {
            path = eq + 1;
        } else if (!strncmp(a, "gpio=", 5)) {
            if (n_ports == MAX_PORTS || parse_u64(eq + 1, &v)) goto bad;
            ports[n_ports++] = v;
        } else if (!strncmp(a, "trace=", 6)) {
            if (parse_u64(eq + 1, &v) || v >= MAX_H) goto bad;
            trace_k = (int)v;
        } else if (!strncmp(a, "over=", 5)) {
            if (parse_u64(eq + 1, &v)) goto bad;
            trace_over = v;
        } else if (sscanf(a, "h%d_%n", &k, &off) == 1 && off > 0 && k >= 0 && k < MAX_H) {
            if (parse_u64(eq + 1, &v)) goto bad;
            if (!strncmp(a + off, "entry=", 6)) {
                hs[k].entry = v;
                hs[k].has_entry = true;
            } else if (!strncmp(a + off, "exit=", 5) && hs[k].n_exits < MAX_EXITS) {
                hs[k].exits[hs[k].n_exits++] = v;
            } else {
                goto bad;
            }
        } else {
            goto bad;
        }
        continue;
    bad:
        fprintf(stderr, "millac_plugin: bad argument '%s'\n", a);
        return -1;
    }
    if (!path) {
        fprintf(stderr, "millac_plugin: missing out=PATH\n");
        return -1;
    }
    snprintf(out_path, sizeof out_path, "%s", path);
    out = fopen(path, "w");
    if (!out) {
        perror("millac_plugin: cannot open out");
        return -1;
    }
    setvbuf(out, NULL, _IOFBF, 1 << 20);
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_tb_trans);
    qemu_plugin_register_atexit_cb(id, on_atexit, NULL);
    return 0;
}
