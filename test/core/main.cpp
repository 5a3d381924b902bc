#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

// Every operator new of the process (the core's too: this definition replaces the library's) is counted, for the
// tests that a warm pipeline allocates nothing (test_pipeline.cpp). OpenCV's images take malloc: those tests check
// the images' buffers by their addresses. Not under ThreadSanitizer, whose static runtime defines operator new
// itself (its build runs test_threads.cpp only, which does not count).
#if defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define KP_TEST_NO_NEW_COUNT
#endif
#endif
#if defined(__SANITIZE_THREAD__)
#define KP_TEST_NO_NEW_COUNT
#endif

#ifndef KP_TEST_NO_NEW_COUNT
namespace
{
std::atomic<long> g_news{0};
}

namespace kp_test
{
long newCalls() { return g_news.load(std::memory_order_relaxed); }
}  // namespace kp_test

void* operator new(std::size_t n)
{
  g_news.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1))
    return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
#endif

int main(int argc, char** argv)
{
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
