/* Fault injection for linebake's "nothing lost on a full disk" tests (issue 27).
 *
 * Preload it (LD_PRELOAD=liblinebake_faults.so) and set, read once at the first call:
 *   LINEBAKE_FAULT_AFTER=N    after N bytes written to regular files (the whole process, all
 *                             files together; fds 1 and 2, pipes and ttys do not count),
 *                             writes fail. A write that straddles N writes up to N and returns
 *                             that short count, as a full disk does; the next one fails.
 *   LINEBAKE_FAULT_ERRNO=E    ENOSPC (default), EDQUOT, EFBIG or EIO (or a number).
 *   LINEBAKE_FAULT_FSYNC=1    fsync and fdatasync fail with E (EIO if LINEBAKE_FAULT_ERRNO is unset).
 *   LINEBAKE_FAULT_FREE=B     statvfs and friends report B bytes free (f_bavail and f_bfree, in
 *                             f_frsize units; f_frsize becomes 1 where B is not a multiple of it).
 *   LINEBAKE_FAULT_CREATE_UNDER=DIR  open, openat and creat that would create a file (O_CREAT
 *                             of a path that does not exist, or with O_EXCL) whose path, as
 *                             given, starts with DIR fail with E (ENOSPC if LINEBAKE_FAULT_ERRNO
 *                             is unset: a file system out of inodes).
 *   LINEBAKE_FAULT_LOG=path   append one line per injected fault: function, fd, bytes (for
 *                             statvfs, the bytes reported free; fd -1 for a path).
 *   LINEBAKE_FAULT_COUNT=path at exit, append "<pid> <bytes>": the bytes this process wrote to
 *                             regular files (counted as for LINEBAKE_FAULT_AFTER), so that a
 *                             clean run measures where "middle" and "late" faults fall.
 *
 * Intercepted: write, pwrite(64), writev, pwritev(64), fwrite, copy_file_range, sendfile,
 * fsync, fdatasync, statvfs(64), fstatvfs(64), open(64), openat(64), creat(64) (fopen and
 * std::ofstream open through glibc's internal calls, which a preload cannot see). glibc's stdio flushes through internal calls
 * that a preload cannot see, so stdio output is counted at fwrite (fputs, fprintf and putc are
 * not seen). Writes through mmap are not seen either.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/sendfile.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <sys/uio.h>
#include <unistd.h>

/* The real functions, found once with dlsym(RTLD_NEXT, ...). */
static ssize_t (*real_write)(int, const void*, size_t);
static ssize_t (*real_pwrite)(int, const void*, size_t, off_t);
static ssize_t (*real_pwrite64)(int, const void*, size_t, off64_t);
static ssize_t (*real_writev)(int, const struct iovec*, int);
static ssize_t (*real_pwritev)(int, const struct iovec*, int, off_t);
static ssize_t (*real_pwritev64)(int, const struct iovec*, int, off64_t);
static size_t (*real_fwrite)(const void*, size_t, size_t, FILE*);
static ssize_t (*real_copy_file_range)(int, off64_t*, int, off64_t*, size_t, unsigned);
static ssize_t (*real_sendfile)(int, int, off_t*, size_t);
static int (*real_fsync)(int);
static int (*real_fdatasync)(int);
static int (*real_statvfs)(const char*, struct statvfs*);
static int (*real_statvfs64)(const char*, struct statvfs64*);
static int (*real_fstatvfs)(int, struct statvfs*);
static int (*real_fstatvfs64)(int, struct statvfs64*);
static int (*real_open)(const char*, int, ...);
static int (*real_open64)(const char*, int, ...);
static int (*real_openat)(int, const char*, int, ...);
static int (*real_openat64)(int, const char*, int, ...);
static int (*real_creat)(const char*, mode_t);
static int (*real_creat64)(const char*, mode_t);

/* Settings. */
static int limit_set;           /* LINEBAKE_FAULT_AFTER given */
static unsigned long long limit;
static int fault_errno = ENOSPC;
static int errno_set;           /* LINEBAKE_FAULT_ERRNO given */
static int fsync_fails;
static int free_set;
static unsigned long long free_bytes;
static const char* log_path;
static const char* create_under; /* LINEBAKE_FAULT_CREATE_UNDER */
static const char* count_path;

static atomic_ullong written; /* bytes written to regular files so far (whole process) */
static pthread_once_t once = PTHREAD_ONCE_INIT;

#define REAL(name) real_##name = dlsym(RTLD_NEXT, #name)

static void init(void) {
  REAL(write); REAL(pwrite); REAL(pwrite64); REAL(writev); REAL(pwritev); REAL(pwritev64);
  REAL(fwrite); REAL(copy_file_range); REAL(sendfile); REAL(fsync); REAL(fdatasync);
  REAL(statvfs); REAL(statvfs64); REAL(fstatvfs); REAL(fstatvfs64);
  REAL(open); REAL(open64); REAL(openat); REAL(openat64); REAL(creat); REAL(creat64);

  const char* s = getenv("LINEBAKE_FAULT_AFTER");
  if (s && *s) { limit_set = 1; limit = strtoull(s, NULL, 10); }
  const char* e = getenv("LINEBAKE_FAULT_ERRNO");
  if (e && *e) {
    errno_set = 1;
    if (!strcmp(e, "ENOSPC")) fault_errno = ENOSPC;
    else if (!strcmp(e, "EDQUOT")) fault_errno = EDQUOT;
    else if (!strcmp(e, "EFBIG")) fault_errno = EFBIG;
    else if (!strcmp(e, "EIO")) fault_errno = EIO;
    else fault_errno = atoi(e) > 0 ? atoi(e) : ENOSPC;
  }
  s = getenv("LINEBAKE_FAULT_FSYNC");
  fsync_fails = s && *s && strcmp(s, "0") != 0;
  s = getenv("LINEBAKE_FAULT_FREE");
  if (s && *s) { free_set = 1; free_bytes = strtoull(s, NULL, 10); }
  create_under = getenv("LINEBAKE_FAULT_CREATE_UNDER");
  if (create_under && !*create_under) create_under = NULL;
  log_path = getenv("LINEBAKE_FAULT_LOG");
  if (log_path && !*log_path) log_path = NULL;
  count_path = getenv("LINEBAKE_FAULT_COUNT");
  if (count_path && *count_path && !limit_set) { limit_set = 1; limit = ~0ULL; } /* count only */
}

static void setup(void) { pthread_once(&once, init); }


/* One line per injected fault, through the real write so that it is never counted. */
static void log_fault(const char* fn, int fd, unsigned long long bytes) {
  if (!log_path) return;
  int saved = errno;
  int lfd = real_open(log_path, O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0644);
  if (lfd >= 0) {
    char line[160];
    int n = snprintf(line, sizeof line, "%s fd=%d bytes=%llu total=%llu pid=%d\n", fn, fd, bytes,
                     (unsigned long long)atomic_load(&written), (int)getpid());
    if (n > 0) (void)!real_write(lfd, line, (size_t)n);
    close(lfd);
  }
  errno = saved;
}

/* Only regular files count and fail; stdout and stderr never do, even redirected to a file. */
/* The byte count for LINEBAKE_FAULT_COUNT, written when the process exits normally. */
__attribute__((destructor)) static void write_count(void) {
  setup();
  if (!count_path || !*count_path) return;
  if (!real_open) return;
  int fd = real_open(count_path, O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) return;
  char line[64];
  int n = snprintf(line, sizeof line, "%d %llu\n", (int)getpid(),
                   (unsigned long long)atomic_load(&written));
  if (n > 0 && real_write) (void)!real_write(fd, line, (size_t)n);
  close(fd);
}

static int is_regular(int fd) {
  struct stat st;
  return fd > 2 && fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
}

/* How many of n bytes to fd may be written: n when not limited, fewer at the limit, 0 past it.
 * The bytes are reserved atomically; give back what the real call did not write. */
static size_t allow(int fd, size_t n) {
  setup();
  if (!limit_set || n == 0 || !is_regular(fd)) return n;
  unsigned long long cur = atomic_load(&written);
  size_t take;
  do {
    if (cur >= limit) return 0;
    take = (unsigned long long)n < limit - cur ? n : (size_t)(limit - cur);
  } while (!atomic_compare_exchange_weak(&written, &cur, cur + take));
  return take;
}

static void give_back(size_t reserved, ssize_t done) {
  if (done < 0) done = 0;
  if ((size_t)done < reserved) atomic_fetch_sub(&written, reserved - (size_t)done);
}

/* The shared shape of the intercepted writes: limit, call, account; fail once nothing is left. */
#define LIMITED_WRITE(fn, fd, n, call)          \
  size_t take = allow(fd, n);                   \
  if (n > 0 && take == 0) {                     \
    log_fault(fn, fd, n);                       \
    errno = fault_errno;                        \
    return -1;                                  \
  }                                             \
  if (take < n) log_fault(fn " (short)", fd, n - take); \
  ssize_t r = call;                             \
  if (limit_set) give_back(take, r);            \
  return r;

ssize_t write(int fd, const void* buf, size_t n) {
  LIMITED_WRITE("write", fd, n, real_write(fd, buf, take))
}
ssize_t pwrite(int fd, const void* buf, size_t n, off_t off) {
  LIMITED_WRITE("pwrite", fd, n, real_pwrite(fd, buf, take, off))
}
ssize_t pwrite64(int fd, const void* buf, size_t n, off64_t off) {
  LIMITED_WRITE("pwrite64", fd, n, real_pwrite64(fd, buf, take, off))
}
ssize_t copy_file_range(int in, off64_t* in_off, int fd, off64_t* off, size_t n, unsigned flags) {
  LIMITED_WRITE("copy_file_range", fd, n, real_copy_file_range(in, in_off, fd, off, take, flags))
}
ssize_t sendfile(int fd, int in, off_t* in_off, size_t n) {
  LIMITED_WRITE("sendfile", fd, n, real_sendfile(fd, in, in_off, take))
}

/* The vector writes: a short write keeps the first `take` bytes of the vectors. */
static size_t iov_bytes(const struct iovec* iov, int cnt) {
  size_t n = 0;
  for (int i = 0; i < cnt; ++i) n += iov[i].iov_len;
  return n;
}
static int iov_cut(const struct iovec* iov, int cnt, size_t take, struct iovec* out) {
  int k = 0;
  for (int i = 0; i < cnt && take > 0 && k < IOV_MAX; ++i, ++k) {
    out[k] = iov[i];
    if (out[k].iov_len > take) out[k].iov_len = take;
    take -= out[k].iov_len;
  }
  return k;
}
#define LIMITED_WRITEV(fn, fd, iov, cnt, call)                             \
  size_t n = iov_bytes(iov, cnt);                                          \
  size_t take = allow(fd, n);                                              \
  if (n > 0 && take == 0) {                                                \
    log_fault(fn, fd, n);                                                  \
    errno = fault_errno;                                                   \
    return -1;                                                             \
  }                                                                        \
  struct iovec cut[IOV_MAX];                                               \
  if (take < n) {                                                          \
    log_fault(fn " (short)", fd, n - take);                                \
    cnt = iov_cut(iov, cnt, take, cut);                                    \
    iov = cut;                                                             \
  }                                                                        \
  ssize_t r = call;                                                        \
  if (limit_set) give_back(take, r);                                       \
  return r;

ssize_t writev(int fd, const struct iovec* iov, int cnt) {
  LIMITED_WRITEV("writev", fd, iov, cnt, real_writev(fd, iov, cnt))
}
ssize_t pwritev(int fd, const struct iovec* iov, int cnt, off_t off) {
  LIMITED_WRITEV("pwritev", fd, iov, cnt, real_pwritev(fd, iov, cnt, off))
}
ssize_t pwritev64(int fd, const struct iovec* iov, int cnt, off64_t off) {
  LIMITED_WRITEV("pwritev64", fd, iov, cnt, real_pwritev64(fd, iov, cnt, off))
}

/* stdio: counted here, before the buffer. A short count (whole items) with errno set is all a
 * preload can portably report; the stream's own error flag stays clear. */
size_t fwrite(const void* buf, size_t size, size_t items, FILE* f) {
  setup();
  size_t n = size * items;
  if (!limit_set || n == 0) return real_fwrite(buf, size, items, f);
  size_t take = allow(fileno(f), n);
  size_t whole = take / size; /* items that fit entirely */
  if (whole < items) {
    log_fault(take == 0 ? "fwrite" : "fwrite (short)", fileno(f), n - whole * size);
    give_back(take, (ssize_t)(whole * size)); /* a partial item is not written */
  }
  size_t done = whole ? real_fwrite(buf, size, whole, f) : 0;
  if (done < whole) give_back(whole * size, (ssize_t)(done * size));
  if (whole < items) errno = fault_errno;
  return done;
}

int fsync(int fd) {
  setup();
  if (fsync_fails) { log_fault("fsync", fd, 0); errno = errno_set ? fault_errno : EIO; return -1; }
  return real_fsync(fd);
}
int fdatasync(int fd) {
  setup();
  if (fsync_fails) { log_fault("fdatasync", fd, 0); errno = errno_set ? fault_errno : EIO; return -1; }
  return real_fdatasync(fd);
}

/* Creating a file under LINEBAKE_FAULT_CREATE_UNDER fails, as on a file system out of inodes. */
static int create_fails(int dir, const char* path, int flags) {
  setup();
  if (!create_under || !(flags & O_CREAT) || strncmp(path, create_under, strlen(create_under)))
    return 0;
  /* An existing file opened with O_CREAT (and no O_EXCL) is not created: it opens. */
  if (!(flags & O_EXCL) && faccessat(dir, path, F_OK, 0) == 0) return 0;
  log_fault("create", -1, 0);
  errno = errno_set ? fault_errno : ENOSPC;
  return 1;
}
static mode_t mode_of(int flags, va_list args) {
  return (flags & O_CREAT) || (flags & O_TMPFILE) == O_TMPFILE ? va_arg(args, mode_t) : 0;
}
#define OPEN(name, DIR, ...)                        \
  do {                                              \
    va_list args;                                   \
    va_start(args, flags);                          \
    const mode_t mode = mode_of(flags, args);       \
    va_end(args);                                   \
    if (create_fails(DIR, path, flags)) return -1;  \
    return real_##name(__VA_ARGS__, flags, mode);   \
  } while (0)
int open(const char* path, int flags, ...) { OPEN(open, AT_FDCWD, path); }
int open64(const char* path, int flags, ...) { OPEN(open64, AT_FDCWD, path); }
int openat(int dir, const char* path, int flags, ...) { OPEN(openat, dir, dir, path); }
int openat64(int dir, const char* path, int flags, ...) { OPEN(openat64, dir, dir, path); }
int creat(const char* path, mode_t mode) {
  return create_fails(AT_FDCWD, path, O_CREAT) ? -1 : real_creat(path, mode);
}
int creat64(const char* path, mode_t mode) {
  return create_fails(AT_FDCWD, path, O_CREAT) ? -1 : real_creat64(path, mode);
}

/* statvfs: B bytes free and available on every file system. */
#define FAKE_FREE(fn, fd, st)                                                  \
  do {                                                                         \
    if (!free_set) break;                                                      \
    log_fault(fn, fd, free_bytes);                                             \
    unsigned long long unit = (st)->f_frsize ? (st)->f_frsize : (st)->f_bsize; \
    if (unit == 0 || free_bytes % unit != 0) {                                 \
      (st)->f_blocks *= unit ? unit : 1; /* the same total, in bytes */        \
      unit = 1;                                                                \
    }                                                                          \
    (st)->f_frsize = unit;                                                     \
    (st)->f_bavail = (st)->f_bfree = free_bytes / unit;                        \
    if ((st)->f_blocks < (st)->f_bfree) (st)->f_blocks = (st)->f_bfree;        \
  } while (0)

int statvfs(const char* path, struct statvfs* st) {
  setup();
  int r = real_statvfs(path, st);
  if (r == 0) FAKE_FREE("statvfs", -1, st);
  return r;
}
int statvfs64(const char* path, struct statvfs64* st) {
  setup();
  int r = real_statvfs64(path, st);
  if (r == 0) FAKE_FREE("statvfs64", -1, st);
  return r;
}
int fstatvfs(int fd, struct statvfs* st) {
  setup();
  int r = real_fstatvfs(fd, st);
  if (r == 0) FAKE_FREE("fstatvfs", fd, st);
  return r;
}
int fstatvfs64(int fd, struct statvfs64* st) {
  setup();
  int r = real_fstatvfs64(fd, st);
  if (r == 0) FAKE_FREE("fstatvfs64", fd, st);
  return r;
}
