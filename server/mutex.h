// A mutex the compiler can check: clang's thread-safety analysis (-Wthread-safety) proves that
// every member declared SF_GUARDED_BY(mutex) is read and written only with that mutex held,
// and that a function declared SF_REQUIRES(mutex) is called only so.
//
// libstdc++'s std::mutex carries no annotations, so the analysis cannot see it: Mutex wraps
// it, and MutexLock is the scoped lock the analysis follows (lock_guard's and unique_lock's
// place). A condition variable waits through MutexLock::Wait, which keeps the lock as far as
// the analysis is concerned; wait loops are written out (`while (!ready) lock.Wait(cv);`)
// rather than with a predicate lambda, whose body the analysis would check as a function of
// its own, holding nothing.
//
// Under GCC the annotations are empty. The check: tests/server/thread_safety_check.sh compiles
// server/ with clang and -Werror=thread-safety on every test run.
#pragma once
#include <chrono>
#include <condition_variable>
#include <mutex>

#if defined(__clang__)
#define SF_THREAD_ANNOTATION(x) __attribute__((x))
#else
#define SF_THREAD_ANNOTATION(x)
#endif

#define SF_CAPABILITY(x) SF_THREAD_ANNOTATION(capability(x))
#define SF_SCOPED_CAPABILITY SF_THREAD_ANNOTATION(scoped_lockable)
#define SF_GUARDED_BY(x) SF_THREAD_ANNOTATION(guarded_by(x))
#define SF_PT_GUARDED_BY(x) SF_THREAD_ANNOTATION(pt_guarded_by(x))
#define SF_REQUIRES(...) SF_THREAD_ANNOTATION(requires_capability(__VA_ARGS__))
#define SF_EXCLUDES(...) SF_THREAD_ANNOTATION(locks_excluded(__VA_ARGS__))
#define SF_ACQUIRE(...) SF_THREAD_ANNOTATION(acquire_capability(__VA_ARGS__))
#define SF_RELEASE(...) SF_THREAD_ANNOTATION(release_capability(__VA_ARGS__))
#define SF_TRY_ACQUIRE(...) SF_THREAD_ANNOTATION(try_acquire_capability(__VA_ARGS__))
#define SF_NO_THREAD_SAFETY_ANALYSIS SF_THREAD_ANNOTATION(no_thread_safety_analysis)

namespace springfit::server {

class SF_CAPABILITY("mutex") Mutex {
 public:
  void lock() SF_ACQUIRE() { mutex_.lock(); }
  void unlock() SF_RELEASE() { mutex_.unlock(); }
  bool try_lock() SF_TRY_ACQUIRE(true) { return mutex_.try_lock(); }

 private:
  friend class MutexLock;
  std::mutex mutex_;
};

class SF_SCOPED_CAPABILITY MutexLock {
 public:
  explicit MutexLock(Mutex& mutex) SF_ACQUIRE(mutex) : lock_(mutex.mutex_) {}
  // Takes over a mutex the caller has locked (Mutex::try_lock).
  MutexLock(Mutex& mutex, std::adopt_lock_t) SF_REQUIRES(mutex)
      : lock_(mutex.mutex_, std::adopt_lock) {}
  ~MutexLock() SF_RELEASE() {}
  MutexLock(const MutexLock&) = delete;
  MutexLock& operator=(const MutexLock&) = delete;

  // Lets go for a while (a call that must not run under the mutex), then takes it again.
  void Unlock() SF_RELEASE() { lock_.unlock(); }
  void Lock() SF_ACQUIRE() { lock_.lock(); }

  // Waits for a notification (or a spurious wake-up): the caller loops on its condition.
  void Wait(std::condition_variable& cv) { cv.wait(lock_); }
  // false: the deadline passed.
  bool WaitUntil(std::condition_variable& cv, std::chrono::steady_clock::time_point deadline) {
    return cv.wait_until(lock_, deadline) == std::cv_status::no_timeout;
  }

 private:
  std::unique_lock<std::mutex> lock_;
};

}  // namespace springfit::server
