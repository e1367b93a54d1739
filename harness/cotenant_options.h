// The co-tenant's options: the [cotenant] section of a profile (harness/experiment_profile.cc
// fills it), owned here because the co-tenant is the module that uses them. Its memory is the
// core's [model] (weights) and the model table's KV-cache geometry (harness/cotenant.h), never a
// copy of either. docs/harness.md gives every default's source.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace zm {

// Where the KV cache's memory lives over time.
enum class KvAllocation {
  // Touched as each request's context grows, given back to the kernel (MADV_DONTNEED) when the
  // request ends: the model of a cache that grows per request.
  kPerRequest,
  // What llama.cpp does: the whole n_ctx cache is allocated and cleared (so resident) when the
  // context is created, and kept.
  kAtLoad,
};
[[nodiscard]] std::string_view KvAllocationName(KvAllocation a);  // "per_request", "at_load"

// How the weights reach memory.
enum class WeightsLoad {
  kMmap,  // llama.cpp's default: the file mapped read-only and shared (page cache, evictable)
  kRead,  // Ollama's own engine and GPU offload: read into process memory (anonymous, not
          // evictable)
};
[[nodiscard]] std::string_view WeightsLoadName(WeightsLoad w);  // "mmap", "read"

struct CotenantOptions {
  std::uint32_t prompt_tokens = 256;
  std::uint32_t answer_tokens = 64;
  std::uint32_t prompt_batch_tokens = 64;  // prompt tokens processed per pass over the weights
  // n_ctx: the KV cache is reserved for this many tokens at start-up (its allocation failing is
  // "failed to start"); prompt + answer must fit. Ollama's default below 24 GiB of VRAM: 4096.
  std::uint32_t context_tokens = 4096;
  double request_period_s = 0.0;  // self-paced program: a request every period; 0 = back to back
  double watchdog_s = 10.0;       // no token for this long inside a request = a stall event
  double restart_delay_s = 3.0;   // supervisor: restart after a death (Ollama's RestartSec=3)
  std::uint64_t kv_bytes_per_token = 0;  // 0 = the model table's (cotenant.h); for other models
  KvAllocation kv_allocation = KvAllocation::kPerRequest;
  WeightsLoad weights_load = WeightsLoad::kMmap;
  bool prefetch = true;     // MAP_POPULATE + MADV_WILLNEED at load, as llama.cpp's loader does
  bool mlock = false;       // llama.cpp --mlock / Ollama use_mlock: off by default in both
  bool cold_start = true;   // drop the file's clean pages first, so this process reads (and is
                            // charged for) them, as after a boot
  std::string weights_dir;  // cache directory of the weights file; empty = DefaultWeightsDir()
};

}  // namespace zm
