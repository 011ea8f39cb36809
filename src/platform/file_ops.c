/* File-system operations Fortran has no standard call for (terrace_file_ops.f90): resolving a
 * path to an absolute one, the kind of an existing path, an atomic rename, advisory locks on the
 * outputs of a running job (flock on a lock file beside each output), and a list of files removed
 * when the process exits (uncommitted temporary outputs and the lock files), so that a run that
 * stops on an error leaves no partial output behind. */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <semaphore.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#define TERRACE_MAX_CLEANUP 64

static char *cleanup_paths[TERRACE_MAX_CLEANUP];
static int cleanup_count = 0;
static int cleanup_installed = 0;

static void terrace_cleanup_at_exit(void)
{
    for (int i = 0; i < cleanup_count; ++i) {
        if (cleanup_paths[i] != NULL) {
            unlink(cleanup_paths[i]);
            free(cleanup_paths[i]);
            cleanup_paths[i] = NULL;
        }
    }
    cleanup_count = 0;
}

/* Unlink the registered files without freeing anything (from a signal handler). */
void terrace_cleanup_signal_safe(void)
{
    for (int i = 0; i < cleanup_count; ++i)
        if (cleanup_paths[i] != NULL) unlink(cleanup_paths[i]);
}

/* Remove the registered files now (the error path calls it before MPI_Finalize / MPI_Abort, so
 * that no rank's exit can let mpirun kill this one before its files are gone). */
void terrace_cleanup_now(void) { terrace_cleanup_at_exit(); }

/* Remove `path` when the process exits, unless terrace_cleanup_forget is called first.
 * Returns 0 on success. */
int terrace_cleanup_register(const char *path)
{
    if (!cleanup_installed) {
        if (atexit(terrace_cleanup_at_exit) != 0) return 1;
        cleanup_installed = 1;
    }
    if (cleanup_count == TERRACE_MAX_CLEANUP) return 1;
    cleanup_paths[cleanup_count] = strdup(path);
    if (cleanup_paths[cleanup_count] == NULL) return 1;
    cleanup_count++;
    return 0;
}

/* Keep `path` at exit (a committed output). */
void terrace_cleanup_forget(const char *path)
{
    for (int i = 0; i < cleanup_count; ++i) {
        if (cleanup_paths[i] != NULL && strcmp(cleanup_paths[i], path) == 0) {
            free(cleanup_paths[i]);
            cleanup_paths[i] = NULL;
        }
    }
}

/* Absolute, symlink-free form of `path` in out (outlen bytes). A path that does not exist yet is
 * resolved through its directory. Returns 0 on success, 1 when the directory does not exist,
 * 2 when the result does not fit. */
int terrace_resolve_path(const char *path, char *out, int outlen)
{
    char buf[PATH_MAX];
    if (realpath(path, buf) == NULL) {
        /* the directory part, then the last component */
        char dir[PATH_MAX];
        const char *slash = strrchr(path, '/');
        const char *base = slash ? slash + 1 : path;
        if (slash == NULL) {
            strcpy(dir, ".");
        } else if (slash == path) {
            strcpy(dir, "/");
        } else {
            size_t n = (size_t)(slash - path);
            if (n >= sizeof dir) return 2;
            memcpy(dir, path, n);
            dir[n] = '\0';
        }
        if (realpath(dir, buf) == NULL) return 1;
        size_t used = strlen(buf);
        if (used + 1 + strlen(base) + 1 > sizeof buf) return 2;
        if (strcmp(buf, "/") != 0) strcat(buf, "/");
        strcat(buf, base);
    }
    if ((int)strlen(buf) + 1 > outlen) return 2;
    strcpy(out, buf);
    return 0;
}

/* The file an output named `path` is written to: `path` itself, or, when `path` is a symbolic
 * link (a chain of them), the file it points to (a dangling link's target is resolved through the
 * link's directory, up to 40 links). Writing there and not over the link keeps the link. Returns 0
 * with the target in out (outlen bytes), 2 when it does not fit. */
int terrace_output_target(const char *path, char *out, int outlen)
{
    char cur[PATH_MAX], link[PATH_MAX], next[PATH_MAX];
    struct stat st;
    if (strlen(path) + 1 > sizeof cur) return 2;
    strcpy(cur, path);
    for (int hops = 0; hops < 40; ++hops) {
        if (lstat(cur, &st) != 0 || !S_ISLNK(st.st_mode)) break;
        if (realpath(cur, next) != NULL) {          /* the target exists: its canonical name */
            strcpy(cur, next);
            break;
        }
        ssize_t n = readlink(cur, link, sizeof link - 1);
        if (n < 0) break;
        link[n] = '\0';
        if (link[0] == '/') {
            strcpy(next, link);
        } else {                                     /* relative to the link's directory */
            const char *slash = strrchr(cur, '/');
            size_t d = slash ? (size_t)(slash - cur) + 1 : 0;
            if (d + (size_t)n + 1 > sizeof next) return 2;
            memcpy(next, cur, d);
            strcpy(next + d, link);
        }
        strcpy(cur, next);
    }
    if ((int)strlen(cur) + 1 > outlen) return 2;
    strcpy(out, cur);
    return 0;
}

/* 0: no such path; 1: a regular file; 2: a directory; 3: something else (device, FIFO, socket). */
int terrace_path_kind(const char *path)
{
    struct stat st;
    if (stat(path, &st) != 0) return 0;
    if (S_ISREG(st.st_mode)) return 1;
    if (S_ISDIR(st.st_mode)) return 2;
    return 3;
}

/* Whether this process may write the existing file `path` (1) or not (0). */
int terrace_writable(const char *path) { return access(path, W_OK) == 0 ? 1 : 0; }

/* rename(2): atomic replacement of `to` by `from` on one file system. Returns errno or 0. */
int terrace_rename(const char *from, const char *to) { return rename(from, to) == 0 ? 0 : errno; }

/* Remove a file; returns errno or 0. */
int terrace_unlink(const char *path) { return unlink(path) == 0 ? 0 : errno; }

/* Take an exclusive advisory lock (flock) on the lock file `path`, created if needed and removed
 * at exit. The descriptor stays open for the life of the process. Returns 0 when locked, 1 when
 * another process holds it, 2 when the lock file cannot be created. */
int terrace_lock_file(const char *path)
{
    int fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0) return 2;
    if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
        int busy = (errno == EWOULDBLOCK);
        close(fd);
        return busy ? 1 : 2;
    }
    terrace_cleanup_register(path);
    return 0;
}

/* The process id (for messages). */
int terrace_pid(void) { return (int)getpid(); }

/* Open MPI's MPI-IO layer (ompio) prepares a shared file pointer at every collective open, which
 * Terrace never uses; its default component (sharedfp/sm) guards it with a POSIX semaphore named
 * after the file's base name only (/dev/shm/sem.OMPIO_<name>), created if absent and waited on. A
 * process killed while it held that semaphore leaves it locked, and every later open of a file of
 * that name on the node would wait forever. Called on every rank before a collective open (and a
 * barrier): the name is removed, so the open creates a fresh one; a job that has the old one open
 * keeps it (an unlinked semaphore lives on for its holders). No-op where there is none. */
void terrace_mpiio_clear_semaphore(const char *path)
{
    const char *base = strrchr(path, '/');
    char name[300];
    base = base ? base + 1 : path;
    snprintf(name, sizeof name, "OMPIO_%s", base);
    (void)sem_unlink(name);
}

/* One entry for the operations on a single path, so that Fortran binds one C function:
 * 1 path kind, 2 writable, 3 unlink, 4 lock, 5 register for removal at exit, 6 forget it,
 * 7 clear the MPI-IO semaphore of its name. */
int terrace_path_op(int op, const char *path)
{
    switch (op) {
    case 1: return terrace_path_kind(path);
    case 2: return terrace_writable(path);
    case 3: return terrace_unlink(path);
    case 4: return terrace_lock_file(path);
    case 5: return terrace_cleanup_register(path);
    case 6: terrace_cleanup_forget(path); return 0;
    case 7: terrace_mpiio_clear_semaphore(path); return 0;
    default: return -1;
    }
}
