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

// Where the stand-in's weights and KV cache live: the profile's one choice ([cotenant] weights).
enum class CotenantWeights {
  // GPU offload on unified memory (llama.cpp with its layers on the GPU, the Jetson; all the
  // paper's models): the weights are copied once into CUDA/NvMap allocations in the shared DRAM
  // (llama.cpp#13856), which the kernel never reclaims. Here: read once into anonymous memory and
  // mlock'ed; the KV cache reserved for n_ctx and locked at load likewise (kv_allocation does not
  // apply). A refused lock is reported ("pinned_refused"), never silent.
  kPinned,
  // CPU backend (llama.cpp's default loader): the file mapped read-only and shared: page cache,
  // evictable, refaulted from the file.
  kMmap,
  // Read into anonymous memory, not locked (Ollama's own engine on the CPU): swappable.
  kRead,
};
[[nodiscard]] std::string_view CotenantWeightsName(CotenantWeights w);  // "pinned", "mmap", "read"
// False when `text` names none of them.
[[nodiscard]] bool ParseCotenantWeights(std::string_view text, CotenantWeights* out);

// How the weights reach memory: the mechanism behind CotenantWeights (harness/weights_file.h).
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
  CotenantWeights weights = CotenantWeights::kPinned;  // the paper's models are GPU-offloaded
  bool prefetch = true;    // mmap: MAP_POPULATE + MADV_WILLNEED at load, as llama.cpp's loader does
  bool cold_start = true;  // drop the file's clean pages first, so this process reads (and is
                           // charged for) them, as after a boot
  std::string weights_dir;  // cache directory of the weights file; empty = DefaultWeightsDir()
};

}  // namespace zm
