#pragma once
//! \file
//! parallel_for: the one way the library spreads work over CPU threads.

#include <functional>

namespace zipfusion {

//! Number of hardware threads (at least 1).
int hardware_threads();

//! Calls body(i) for every i in [begin, end), spread over up to num_threads threads
//! (0 = hardware_threads()). Indices are split into contiguous blocks, one per thread; each
//! body call must write only its own output. Blocks until all calls return; the first exception
//! thrown by a body is rethrown here after all threads have stopped.
void parallel_for(int begin, int end, const std::function<void(int)>& body, int num_threads = 0);

}  // namespace zipfusion
