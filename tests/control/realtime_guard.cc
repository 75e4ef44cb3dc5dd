#include "tests/control/realtime_guard.h"

#include <dlfcn.h>
#include <malloc.h>
#include <poll.h>
#include <pthread.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <new>

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define VISCO_FULL_HOOKS 0
#else
#define VISCO_FULL_HOOKS 1
#endif

namespace {

__attribute__((tls_model("initial-exec"))) thread_local bool g_active = false;
__attribute__((tls_model("initial-exec"))) thread_local visco::control::testing::RealtimeCounts g_counts;

inline void Count(std::int64_t visco::control::testing::RealtimeCounts::*field) {
  if (g_active) ++(g_counts.*field);
}

}  // namespace

namespace visco::control::testing {

bool FullHooksActive() { return VISCO_FULL_HOOKS != 0; }
RealtimeGuard::RealtimeGuard() {
  g_counts = RealtimeCounts{};
  g_active = true;
}
RealtimeGuard::~RealtimeGuard() { g_active = false; }
RealtimeCounts RealtimeGuard::counts() const { return g_counts; }

}  // namespace visco::control::testing

using visco::control::testing::RealtimeCounts;

// operator new / delete: every variant, on top of malloc/free.
void* operator new(std::size_t n) {
  Count(&RealtimeCounts::allocations);
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  Count(&RealtimeCounts::allocations);
  return std::malloc(n == 0 ? 1 : n);
}
void* operator new[](std::size_t n, const std::nothrow_t& t) noexcept { return operator new(n, t); }
void* operator new(std::size_t n, std::align_val_t a) {
  Count(&RealtimeCounts::allocations);
  const std::size_t align = static_cast<std::size_t>(a);
  if (void* p = std::aligned_alloc(align, (n + align - 1) / align * align)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t a) { return operator new(n, a); }
void operator delete(void* p) noexcept {
  if (p != nullptr) Count(&RealtimeCounts::frees);
  std::free(p);
}
void operator delete[](void* p) noexcept { operator delete(p); }
void operator delete(void* p, std::size_t) noexcept { operator delete(p); }
void operator delete[](void* p, std::size_t) noexcept { operator delete(p); }
void operator delete(void* p, std::align_val_t) noexcept { operator delete(p); }
void operator delete[](void* p, std::align_val_t) noexcept { operator delete(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { operator delete(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { operator delete(p); }

#if VISCO_FULL_HOOKS
// glibc lets a program replace malloc; the originals stay reachable as __libc_*.
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void __libc_free(void*);
void* __libc_memalign(std::size_t, std::size_t);

void* malloc(std::size_t n) {
  Count(&RealtimeCounts::allocations);
  return __libc_malloc(n);
}
void* calloc(std::size_t n, std::size_t size) {
  Count(&RealtimeCounts::allocations);
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t n) {
  Count(&RealtimeCounts::allocations);
  return __libc_realloc(p, n);
}
void free(void* p) {
  if (p != nullptr) Count(&RealtimeCounts::frees);
  __libc_free(p);
}
void* memalign(std::size_t align, std::size_t n) {
  Count(&RealtimeCounts::allocations);
  return __libc_memalign(align, n);
}
void* aligned_alloc(std::size_t align, std::size_t n) {
  Count(&RealtimeCounts::allocations);
  return __libc_memalign(align, n);
}
int posix_memalign(void** out, std::size_t align, std::size_t n) {
  Count(&RealtimeCounts::allocations);
  void* p = __libc_memalign(align, n);
  if (p == nullptr) return 12;  // ENOMEM
  *out = p;
  return 0;
}
void* valloc(std::size_t n) {
  Count(&RealtimeCounts::allocations);
  return __libc_memalign(static_cast<std::size_t>(sysconf(_SC_PAGESIZE)), n);
}

// Functions forwarded to the next definition (libc), resolved once before main.
#define VISCO_NEXT(name) reinterpret_cast<decltype(&name)>(dlsym(RTLD_NEXT, #name))
static decltype(&pthread_mutex_lock) real_mutex_lock;
static decltype(&pthread_mutex_trylock) real_mutex_trylock;
static decltype(&read) real_read;
static decltype(&write) real_write;
static decltype(&send) real_send;
static decltype(&sendto) real_sendto;
static decltype(&sendmsg) real_sendmsg;
static decltype(&recv) real_recv;
static decltype(&recvfrom) real_recvfrom;
static decltype(&recvmsg) real_recvmsg;
static decltype(&poll) real_poll;
static decltype(&select) real_select;
static decltype(&fwrite) real_fwrite;
static decltype(&fputs) real_fputs;
static decltype(&puts) real_puts;
static decltype(&vfprintf) real_vfprintf;
using CxaThrow = void (*)(void*, void*, void (*)(void*));
static CxaThrow real_cxa_throw;

__attribute__((constructor)) static void ResolveHooks() {
  real_mutex_lock = VISCO_NEXT(pthread_mutex_lock);
  real_mutex_trylock = VISCO_NEXT(pthread_mutex_trylock);
  real_read = VISCO_NEXT(read);
  real_write = VISCO_NEXT(write);
  real_send = VISCO_NEXT(send);
  real_sendto = VISCO_NEXT(sendto);
  real_sendmsg = VISCO_NEXT(sendmsg);
  real_recv = VISCO_NEXT(recv);
  real_recvfrom = VISCO_NEXT(recvfrom);
  real_recvmsg = VISCO_NEXT(recvmsg);
  real_poll = VISCO_NEXT(poll);
  real_select = VISCO_NEXT(select);
  real_fwrite = VISCO_NEXT(fwrite);
  real_fputs = VISCO_NEXT(fputs);
  real_puts = VISCO_NEXT(puts);
  real_vfprintf = VISCO_NEXT(vfprintf);
  real_cxa_throw = reinterpret_cast<CxaThrow>(dlsym(RTLD_NEXT, "__cxa_throw"));
}

int pthread_mutex_lock(pthread_mutex_t* m) {
  Count(&RealtimeCounts::locks);
  return real_mutex_lock(m);
}
int pthread_mutex_trylock(pthread_mutex_t* m) {
  Count(&RealtimeCounts::locks);
  return real_mutex_trylock(m);
}
ssize_t read(int fd, void* buf, std::size_t n) {
  Count(&RealtimeCounts::io);
  return real_read(fd, buf, n);
}
ssize_t write(int fd, const void* buf, std::size_t n) {
  Count(&RealtimeCounts::io);
  return real_write(fd, buf, n);
}
ssize_t send(int fd, const void* buf, std::size_t n, int flags) {
  Count(&RealtimeCounts::io);
  return real_send(fd, buf, n, flags);
}
ssize_t sendto(int fd, const void* buf, std::size_t n, int flags, const sockaddr* to, socklen_t len) {
  Count(&RealtimeCounts::io);
  return real_sendto(fd, buf, n, flags, to, len);
}
ssize_t sendmsg(int fd, const msghdr* msg, int flags) {
  Count(&RealtimeCounts::io);
  return real_sendmsg(fd, msg, flags);
}
ssize_t recv(int fd, void* buf, std::size_t n, int flags) {
  Count(&RealtimeCounts::io);
  return real_recv(fd, buf, n, flags);
}
ssize_t recvfrom(int fd, void* buf, std::size_t n, int flags, sockaddr* from, socklen_t* len) {
  Count(&RealtimeCounts::io);
  return real_recvfrom(fd, buf, n, flags, from, len);
}
ssize_t recvmsg(int fd, msghdr* msg, int flags) {
  Count(&RealtimeCounts::io);
  return real_recvmsg(fd, msg, flags);
}
int poll(pollfd* fds, nfds_t n, int timeout) {
  Count(&RealtimeCounts::io);
  return real_poll(fds, n, timeout);
}
int select(int n, fd_set* r, fd_set* w, fd_set* e, timeval* t) {
  Count(&RealtimeCounts::io);
  return real_select(n, r, w, e, t);
}
std::size_t fwrite(const void* p, std::size_t size, std::size_t n, FILE* f) {
  Count(&RealtimeCounts::io);
  return real_fwrite(p, size, n, f);
}
int fputs(const char* s, FILE* f) {
  Count(&RealtimeCounts::io);
  return real_fputs(s, f);
}
int puts(const char* s) {
  Count(&RealtimeCounts::io);
  return real_puts(s);
}
int vfprintf(FILE* f, const char* format, va_list args) {
  Count(&RealtimeCounts::io);
  return real_vfprintf(f, format, args);
}
int fprintf(FILE* f, const char* format, ...) {
  va_list args;
  va_start(args, format);
  const int n = vfprintf(f, format, args);
  va_end(args);
  return n;
}
int printf(const char* format, ...) {
  va_list args;
  va_start(args, format);
  const int n = vfprintf(stdout, format, args);
  va_end(args);
  return n;
}
[[noreturn]] void __cxa_throw(void* exception, void* type, void (*destructor)(void*)) {
  Count(&RealtimeCounts::throws);
  real_cxa_throw(exception, type, destructor);
  __builtin_unreachable();
}
}  // extern "C"
#endif
