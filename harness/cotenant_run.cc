// The co-tenant's run loop: load the weights file, reserve the KV cache, serve requests (prompt
// processing then decode, streaming the weights per pass), a watchdog on token progress, and one
// event line per start, request, stall and end. See cotenant.h.
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <optional>
#include <thread>

#include "harness/cotenant.h"
#include "harness/device_ledger.h"
#include "harness/weights_file.h"
#include "runtime/budget.h"

namespace zm {
namespace {

bool Stopped(const std::atomic<bool>* stop) {
  return stop != nullptr && stop->load(std::memory_order_relaxed);
}

// Sleeps until the monotonic time `until_s`, waking early when *stop is set.
void SleepUntil(double until_s, const std::atomic<bool>* stop) {
  for (;;) {
    const double left = until_s - MonotonicSeconds();
    if (left <= 0.0 || Stopped(stop)) return;
    std::this_thread::sleep_for(std::chrono::duration<double>(std::min(left, 0.005)));
  }
}

// One forward pass's memory traffic: every 64-bit word of `words`, in eight independent lanes so
// the loop is limited by memory bandwidth rather than an add chain. The result seeds the next
// pass and ends in the reported checksum; the barrier keeps the compiler from merging passes.
[[gnu::noinline]] std::uint64_t StreamPass(const std::uint64_t* w, std::size_t words,
                                           std::uint64_t seed) {
  std::uint64_t a[8] = {seed, 1, 2, 3, 4, 5, 6, 7};
  std::size_t i = 0;
  for (; i + 8 <= words; i += 8) {
    for (std::size_t k = 0; k < 8; ++k) a[k] += w[i + k];
  }
  for (; i < words; ++i) a[0] += w[i];
  std::uint64_t h = 0;
  for (std::uint64_t v : a) h = (h ^ v) * 0x100000001B3ULL;
  asm volatile("" : : "r"(h) : "memory");
  return h;
}

std::uint64_t PageRound(std::uint64_t bytes) {
  const auto page = static_cast<std::uint64_t>(sysconf(_SC_PAGESIZE));
  return (bytes + page - 1) / page * page;
}

// The KV cache: anonymous memory reserved for n_ctx tokens at start-up (the allocation that can
// fail "to start"), written as the context grows, read by every decode step, and given back to the
// kernel at the end of a request (per_request) or kept (at_load).
class KvCache {
 public:
  KvCache() = default;
  KvCache(const KvCache&) = delete;
  KvCache& operator=(const KvCache&) = delete;
  ~KvCache() {
    if (base_ != nullptr) munmap(base_, reserved_);
  }

  Status Reserve(std::uint64_t bytes) {
    if (bytes == 0) return Status::Ok();
    reserved_ = static_cast<std::size_t>(PageRound(bytes));
    void* p = mmap(nullptr, reserved_, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) {
      const int e = errno;
      reserved_ = 0;
      return ResourceExhausted("allocating the " + FormatBytes(bytes) +
                               " KV cache failed: " + std::strerror(e));
    }
    base_ = static_cast<unsigned char*>(p);
    return Status::Ok();
  }
  // Writes the cache up to `bytes` (the new entries of the context).
  void GrowTo(std::uint64_t bytes) {
    const std::size_t to = std::min<std::size_t>(static_cast<std::size_t>(bytes), reserved_);
    if (to > touched_) {
      std::memset(base_ + touched_, 0x5A, to - touched_);
      touched_ = to;
    }
  }
  // Attention reads the whole context's K and V.
  std::uint64_t Read(std::uint64_t seed) const {
    return touched_ < 8
               ? seed
               : StreamPass(reinterpret_cast<const std::uint64_t*>(base_), touched_ / 8, seed);
  }
  // Pinned (CotenantWeights::kPinned): the whole reservation resident and locked, as a CUDA
  // allocation made when the context is created. 0 or the errno of mlock.
  int Lock() {
    if (reserved_ == 0) return 0;
    if (const int e = LockPages(base_, reserved_); e != 0) return e;
    locked_ = true;
    return 0;
  }
  // Gives the pages back (MADV_DONTNEED: the next touch gets fresh zero pages); a locked cache
  // keeps them, as llama.cpp's device buffer does.
  void Release() {
    if (touched_ > 0 && !locked_) {
      madvise(base_, static_cast<std::size_t>(PageRound(touched_)), MADV_DONTNEED);
    }
    touched_ = 0;
  }
  // Bytes of the written part that are resident now (mincore).
  std::uint64_t ResidentBytes() {
    const std::size_t page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
    const std::size_t pages = (touched_ + page - 1) / page;
    if (pages == 0) return 0;
    vec_.resize(pages);
    if (mincore(base_, pages * page, vec_.data()) != 0) return 0;
    std::uint64_t n = 0;
    for (unsigned char v : vec_) n += (v & 1u) ? page : 0;
    return std::min<std::uint64_t>(n, touched_);
  }
  [[nodiscard]] std::uint64_t touched() const { return touched_; }
  [[nodiscard]] std::uint64_t reserved() const { return reserved_; }

 private:
  unsigned char* base_ = nullptr;
  std::size_t reserved_ = 0;
  std::size_t touched_ = 0;
  bool locked_ = false;
  std::vector<unsigned char> vec_;  // mincore's output, kept between requests
};

// Serializes event lines from the worker and the watchdog, and folds them into the report.
class Emitter {
 public:
  Emitter(std::function<void(std::string_view)> sink, double device_scale, double origin)
      : sink_(std::move(sink)), device_scale_(device_scale), builder_(origin) {}
  void Emit(nlohmann::json j) {
    j["stand_in"] = true;
    j["pid"] = static_cast<std::int64_t>(getpid());
    j["mono_s"] = MonotonicSeconds();
    j["device_scale"] = device_scale_;
    std::lock_guard<std::mutex> lock(mu_);
    (void)builder_.Add(j);
    if (sink_) sink_(j.dump());
  }
  CotenantResult Report() {
    std::lock_guard<std::mutex> lock(mu_);
    return builder_.Report();
  }

 private:
  std::function<void(std::string_view)> sink_;
  double device_scale_;
  std::mutex mu_;
  CotenantReportBuilder builder_;
};

// No token for watchdog_s inside a request is a stall: reported by the watchdog thread while it
// lasts, or by the worker when the late token finally comes (if the whole process was frozen,
// the thread could not report it), once per gap either way.
class Watchdog {
 public:
  using OnStall = std::function<void(std::uint64_t id, double gap_s)>;
  Watchdog(double watchdog_s, OnStall on_stall)
      : limit_s_(watchdog_s), on_stall_(std::move(on_stall)) {
    if (limit_s_ > 0.0) thread_ = std::thread([this] { Loop(); });
  }
  Watchdog(const Watchdog&) = delete;
  Watchdog& operator=(const Watchdog&) = delete;
  ~Watchdog() {
    {
      std::lock_guard<std::mutex> lock(mu_);
      quit_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

  void Begin(std::uint64_t id) {
    std::lock_guard<std::mutex> lock(mu_);
    in_request_ = true;
    id_ = id;
    last_s_ = MonotonicSeconds();
    fired_ = false;
    stalls_ = 0;
    max_gap_s_ = 0.0;
  }
  void Progress() {
    const double now = MonotonicSeconds();
    std::optional<double> late;
    std::uint64_t id = 0;
    {
      std::lock_guard<std::mutex> lock(mu_);
      const double gap = now - last_s_;
      max_gap_s_ = std::max(max_gap_s_, gap);
      if (limit_s_ > 0.0 && gap > limit_s_ && !fired_) {
        ++stalls_;
        late = gap;
        id = id_;
      }
      last_s_ = now;
      fired_ = false;
    }
    if (late) on_stall_(id, *late);
  }
  struct Summary {
    std::uint32_t stalls = 0;
    double max_gap_s = 0.0;
  };
  Summary End() {
    std::lock_guard<std::mutex> lock(mu_);
    in_request_ = false;
    return {stalls_, max_gap_s_};
  }

 private:
  void Loop() {
    const auto period = std::chrono::duration<double>(std::clamp(limit_s_ / 4.0, 0.001, 0.25));
    std::unique_lock<std::mutex> lock(mu_);
    while (!quit_) {
      cv_.wait_for(lock, period);
      if (quit_ || !in_request_ || fired_) continue;
      const double gap = MonotonicSeconds() - last_s_;
      if (gap > limit_s_) {
        fired_ = true;
        ++stalls_;
        const std::uint64_t id = id_;
        lock.unlock();
        on_stall_(id, gap);
        lock.lock();
      }
    }
  }

  const double limit_s_;
  OnStall on_stall_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool quit_ = false;
  bool in_request_ = false;
  bool fired_ = false;
  std::uint64_t id_ = 0;
  double last_s_ = 0.0;
  std::uint32_t stalls_ = 0;
  double max_gap_s_ = 0.0;
  std::thread thread_;
};

rusage ThreadUsage() {
  rusage u{};
  getrusage(RUSAGE_THREAD, &u);
  return u;
}

}  // namespace

CotenantResult RunCotenant(const CotenantConfig& config, const std::atomic<bool>* stop,
                           CotenantHooks hooks) {
  const double origin = MonotonicSeconds();
  Emitter em(std::move(hooks.emit), config.device_scale, origin);
  const CotenantOptions& o = config.options;
  auto fail = [&](const std::string& reason, const CotenantSizes* s) {
    nlohmann::json j = {{"event", "failed_to_start"},
                        {"reason", reason},
                        {"model", config.model},
                        {"note", std::string(kCotenantNote)}};
    if (s != nullptr) {
      j["model_weights_bytes"] = s->model_weights_bytes;
      j["weights_bytes"] = s->weights_bytes;
      j["kv_reserved_bytes"] = s->kv_reserved_bytes;
      j["request_kv_bytes"] = s->request_kv_bytes;
      j["context_tokens"] = o.context_tokens;
    }
    em.Emit(std::move(j));
    return em.Report();
  };

  Result<CotenantSizes> sized = ResolveCotenantSizes(config);
  if (!sized.ok()) return fail(sized.status().message(), nullptr);
  const CotenantSizes& sz = *sized;
  if (hooks.await_start && !hooks.await_start()) return fail("stopped before it started", &sz);

  // The device ledger (the portable fallback): the weights (and an at_load KV cache) must be
  // granted to start; each request's KV cache is asked for per request.
  std::optional<DeviceLedger> ledger;
  LedgerTenant tenant;
  const std::uint64_t base_grant = sz.weights_bytes + (o.kv_allocation == KvAllocation::kAtLoad ||
                                                               o.weights == CotenantWeights::kPinned
                                                           ? sz.kv_reserved_bytes
                                                           : 0);
  if (!config.ledger_path.empty()) {
    Result<DeviceLedger> opened =
        DeviceLedger::Open(config.ledger_path, config.ledger_device_bytes);
    if (!opened.ok()) return fail(opened.status().message(), &sz);
    ledger.emplace(std::move(opened).value());
    const std::string name =
        config.ledger_name.empty() ? "cotenant:" + config.model : config.ledger_name;
    Result<LedgerTenant> t = ledger->Register(name, base_grant);
    if (!t.ok()) return fail("the device ledger refused the weights: " + t.status().message(), &sz);
    tenant = std::move(t).value();
  }

  Result<WeightsFileInfo> file = EnsureWeightsFile(o.weights_dir, sz.weights_bytes);
  if (!file.ok()) return fail("the weights could not be mapped: " + file.status().message(), &sz);
  WeightsMapOptions mo;
  const bool pinned = o.weights == CotenantWeights::kPinned;
  mo.load = o.weights == CotenantWeights::kMmap ? WeightsLoad::kMmap : WeightsLoad::kRead;
  mo.prefetch = o.prefetch;
  mo.mlock = pinned;
  mo.cold_start = o.cold_start;
  Result<MappedWeights> mapped = MappedWeights::Map(file->path, mo);
  if (!mapped.ok())
    return fail("the weights could not be mapped: " + mapped.status().message(), &sz);
  const MappedWeights& weights = *mapped;
  KvCache kv;
  if (Status s = kv.Reserve(sz.kv_reserved_bytes); !s.ok()) {
    return fail("the KV cache could not be allocated (" + std::to_string(o.context_tokens) +
                    " tokens of context): " + s.message(),
                &sz);
  }
  // Pinned: the KV cache is a device buffer made with the context, resident and locked; else as
  // kv_allocation says.
  const KvAllocation kv_allocation = pinned ? KvAllocation::kAtLoad : o.kv_allocation;
  std::string lock_error = weights.mlock_error();
  if (pinned) {
    if (const int e = kv.Lock(); e != 0 && lock_error.empty()) {
      lock_error = "mlock of the " + FormatBytes(kv.reserved()) +
                   " KV cache failed: " + std::strerror(e) + " (RLIMIT_MEMLOCK)";
    }
  }
  if (kv_allocation == KvAllocation::kAtLoad) kv.GrowTo(kv.reserved());  // cleared at load
  const std::string weights_mode = !pinned ? std::string(CotenantWeightsName(o.weights))
                                   : lock_error.empty() ? std::string("pinned")
                                                        : std::string("pinned_refused");
  if (!lock_error.empty()) {
    // Never silent: the weights are then ordinary anonymous memory the kernel may swap.
    std::fprintf(stderr, "zonemap-cotenant: weights pinned_refused: %s\n", lock_error.c_str());
  }

  em.Emit({{"event", "start"},
           {"note", std::string(kCotenantNote)},
           {"model", config.model},
           {"model_weights_bytes", sz.model_weights_bytes},
           {"weights_bytes", sz.weights_bytes},
           {"weights_path", file->path},
           {"weights_file_created", file->created},
           {"weights_create_ms", file->create_ms},
           {"weights_fs", file->fs_type},
           {"weights", weights_mode},
           {"weights_load", std::string(WeightsLoadName(mo.load))},
           {"file_backed", weights.file_backed()},
           {"evictable", weights.file_backed() && file->evictable && !weights.locked()},
           {"prefetch", o.prefetch},
           {"cold_start", o.cold_start},
           {"mlock", pinned},
           {"mlocked", weights.locked()},
           {"mlock_error", lock_error},
           {"load_ms", weights.load_ms()},
           {"kv_bytes_per_token", sz.model.kv_bytes_per_token},
           {"kv_window_bytes_per_token", sz.model.window_bytes_per_token},
           {"kv_window_tokens", sz.model.window_tokens},
           {"kv_state_bytes", sz.model.state_bytes},
           {"kv_allocation", std::string(KvAllocationName(kv_allocation))},
           {"context_tokens", o.context_tokens},
           {"kv_reserved_bytes", sz.kv_reserved_bytes},
           {"request_kv_bytes", sz.request_kv_bytes},
           {"prompt_tokens", o.prompt_tokens},
           {"answer_tokens", o.answer_tokens},
           {"prompt_batch_tokens", o.prompt_batch_tokens},
           {"watchdog_s", sz.watchdog_s},
           {"watchdog_full_size_s", o.watchdog_s}});

  Watchdog watchdog(sz.watchdog_s, [&](std::uint64_t id, double gap_s) {
    em.Emit(
        {{"event", "stall"}, {"id", id}, {"since_token_s", gap_s}, {"watchdog_s", sz.watchdog_s}});
  });

  std::uint32_t served = 0;
  auto self_paced = [&](CotenantTicket& t) {
    if (config.requests != 0 && served >= config.requests) return false;
    const double due = origin + served * o.request_period_s;
    SleepUntil(due, stop);
    if (Stopped(stop)) return false;
    t.id = served;
    t.submitted_mono_s = o.request_period_s > 0.0 ? due : MonotonicSeconds();
    return true;
  };
  std::function<bool(CotenantTicket&)> next =
      hooks.next_request ? std::move(hooks.next_request)
                         : std::function<bool(CotenantTicket&)>(self_paced);

  const std::size_t words = weights.bytes() / 8;
  const std::uint32_t prefill_passes =
      (o.prompt_tokens + o.prompt_batch_tokens - 1) / o.prompt_batch_tokens;
  std::uint64_t h = 0;
  CotenantTicket ticket;
  while (!Stopped(stop) && next(ticket)) {
    ++served;
    if (ledger &&
        !tenant.TryUpdate(base_grant +
                          (kv_allocation == KvAllocation::kPerRequest ? sz.request_kv_bytes : 0))) {
      em.Emit({{"event", "request_failed"},
               {"id", ticket.id},
               {"submitted_s", ticket.submitted_mono_s},
               {"reason", "the device ledger refused its " + FormatBytes(sz.request_kv_bytes) +
                              " KV cache"}});
      (void)tenant.Update(base_grant);  // withdraw the demand: the request is given up
      continue;
    }
    const double started = MonotonicSeconds();
    em.Emit({{"event", "request_start"}, {"id", ticket.id}, {"started_s", started}});
    const rusage u0 = ThreadUsage();
    watchdog.Begin(ticket.id);
    bool aborted = false;
    std::uint64_t context = 0;
    for (std::uint32_t p = 0; p < prefill_passes && !aborted; ++p) {
      aborted = Stopped(stop);
      if (aborted) break;
      context =
          std::min<std::uint64_t>(o.prompt_tokens, std::uint64_t{p + 1} * o.prompt_batch_tokens);
      kv.GrowTo(ScaledKvBytes(sz, config.device_scale, context));
      h = kv.Read(StreamPass(weights.words(), words, h));
      watchdog.Progress();
    }
    const double prefilled = MonotonicSeconds();
    for (std::uint32_t t = 0; t < o.answer_tokens && !aborted; ++t) {
      aborted = Stopped(stop);
      if (aborted) break;
      context = std::uint64_t{o.prompt_tokens} + t + 1;
      kv.GrowTo(ScaledKvBytes(sz, config.device_scale, context));
      h = kv.Read(StreamPass(weights.words(), words, h + t));
      watchdog.Progress();
    }
    const double ended = MonotonicSeconds();
    const Watchdog::Summary ws = watchdog.End();
    const rusage u1 = ThreadUsage();
    const std::uint64_t kv_bytes = kv.touched();
    const std::uint64_t kv_resident = kv.ResidentBytes();
    if (kv_allocation == KvAllocation::kPerRequest) kv.Release();
    if (ledger) (void)tenant.Update(base_grant);
    if (aborted) {
      em.Emit({{"event", "request_failed"},
               {"id", ticket.id},
               {"unfinished", true},
               {"submitted_s", ticket.submitted_mono_s},
               {"started_s", started},
               {"reason", "stopped mid-request"}});
      break;
    }
    const double prefill_ms = (prefilled - started) * 1000.0;
    const double decode_ms = (ended - prefilled) * 1000.0;
    em.Emit(
        {{"event", "request"},
         {"id", ticket.id},
         {"submitted_s", ticket.submitted_mono_s},
         {"started_s", started},
         {"ended_s", ended},
         {"prompt_tokens", o.prompt_tokens},
         {"answer_tokens", o.answer_tokens},
         {"prefill_ms", prefill_ms},
         {"decode_ms", decode_ms},
         {"latency_ms", (ended - started) * 1000.0},
         {"queue_ms", std::max(0.0, (started - ticket.submitted_mono_s) * 1000.0)},
         {"tokens_per_s", decode_ms > 0.0 ? o.answer_tokens * 1000.0 / decode_ms : 0.0},
         {"prefill_tokens_per_s", prefill_ms > 0.0 ? o.prompt_tokens * 1000.0 / prefill_ms : 0.0},
         {"kv_bytes", kv_bytes},
         {"kv_resident_bytes", kv_resident},
         {"major_faults", static_cast<std::uint64_t>(u1.ru_majflt - u0.ru_majflt)},
         {"minor_faults", static_cast<std::uint64_t>(u1.ru_minflt - u0.ru_minflt)},
         {"max_token_gap_ms", ws.max_gap_s * 1000.0},
         {"stalls", ws.stalls}});
  }
  em.Emit({{"event", "end"},
           {"reason", Stopped(stop) ? "stopped" : "no more requests"},
           {"requests_served", served},
           {"checksum", h}});
  return em.Report();
}

}  // namespace zm
