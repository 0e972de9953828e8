#pragma once
//! \file
//! parallel_for: the one way the library spreads work over CPU threads.

#include <memory>
#include <type_traits>
#include <utility>

namespace zipfusion {

//! A non-owning reference to a callable taking an int, for parallel_for: unlike std::function it
//! never allocates (a lambda that captures more than two pointers made std::function allocate at
//! every call, dozens of times a frame set). The callable must outlive the reference; a function
//! is passed by its address (&f).
class IndexFunctionRef {
 public:
  template <typename F>
    requires(!std::is_same_v<std::remove_cvref_t<F>, IndexFunctionRef> && !std::is_function_v<std::remove_reference_t<F>> &&
             std::is_invocable_v<F&, int>)
  IndexFunctionRef(F&& f)  // NOLINT(google-explicit-constructor): lambdas convert as to std::function
      : object_(const_cast<void*>(static_cast<const void*>(std::addressof(f)))),
        call_([](void* object, int i) { (*static_cast<std::remove_reference_t<F>*>(object))(i); }) {}

  void operator()(int i) const { call_(object_, i); }

 private:
  void* object_;
  void (*call_)(void*, int);
};

//! Number of hardware threads (at least 1).
int hardware_threads();

//! Calls body(i) for every i in [begin, end), spread over up to num_threads threads
//! (0 = hardware_threads()). Indices are split into contiguous blocks, one per thread; each
//! body call must write only its own output. `body` itself (not a copy) is called from several
//! threads at once. Blocks until all calls return; the first exception thrown by a body is
//! rethrown here after all threads have stopped. Allocates nothing once the pool's queue has
//! grown to the most blocks ever pending at once.
void parallel_for(int begin, int end, IndexFunctionRef body, int num_threads = 0);

}  // namespace zipfusion
