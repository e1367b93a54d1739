// The evaluation's profile sections: [cotenant] read by the harness from the same files as the
// core; --cotenant MODEL swaps [model] for one of the paper's models and keeps the map share.
#include "harness/experiment_profile.h"

#include <doctest/doctest.h>

#include <filesystem>

#include "support/test_util.h"

namespace zm {
namespace {

using test::Contains;

TEST_CASE("every shipped profile loads with its harness sections") {
  int loaded = 0;
  for (const auto& entry : std::filesystem::directory_iterator(ZM_SOURCE_DIR "/profiles")) {
    if (entry.path().extension() != ".toml") continue;
    CAPTURE(entry.path().string());
    Result<ExperimentProfile> p = LoadExperimentProfile(entry.path().string());
    REQUIRE_MESSAGE(p.ok(), p.status().ToString());
    CHECK(p->cotenant.answer_tokens > 0);
    // The Jetson profiles: GPU-offloaded weights pinned, JetPack's zram of half the memory.
    if (entry.path().filename().string().rfind("orin-nano-8gb", 0) == 0) {
      CHECK(p->cotenant.weights == CotenantWeights::kPinned);
      CHECK(p->core.device.swap == "zram");
      CHECK(p->core.device.swap_bytes == 3886ULL * 1024 * 1024);
    }
    ++loaded;
  }
  CHECK(loaded >= 3);
}

TEST_CASE("[cotenant] keys are checked like the core's") {
  Result<ExperimentProfile> p =
      ParseExperimentProfile("[cotenant]\nprompt_tokens = 9\nanswer_tokens = 3\n", "co.toml");
  REQUIRE(p.ok());
  CHECK(p->cotenant.prompt_tokens == 9);
  CHECK(p->cotenant.answer_tokens == 3);
  Result<ExperimentProfile> bad = ParseExperimentProfile("[cotenant]\nmodel = \"x\"\n", "bad.toml");
  REQUIRE_FALSE(bad.ok());
  CHECK(Contains(bad.status().message(), "'cotenant.model'"));
  bad = ParseExperimentProfile("[cotenant]\nanswer_tokens = 0\n", "bad.toml");
  REQUIRE_FALSE(bad.ok());
  CHECK(Contains(bad.status().message(), "'cotenant.answer_tokens'"));
  bad = ParseExperimentProfile("[gpu]\ncores = 1\n", "bad.toml");
  REQUIRE_FALSE(bad.ok());
  CHECK(Contains(bad.status().message(), "'gpu'"));
}

TEST_CASE("[cotenant]'s co-tenant keys: enums by name, the context holds a request") {
  Result<ExperimentProfile> p = ParseExperimentProfile(
      "[cotenant]\nkv_allocation = \"at_load\"\nweights = \"read\"\nprefetch = false\n"
      "watchdog_s = 2.5\nrestart_delay_s = 0\ncontext_tokens = 1024\nkv_bytes_per_token = "
      "\"1KiB\"\n",
      "co.toml");
  REQUIRE_MESSAGE(p.ok(), p.status().ToString());
  CHECK(p->cotenant.kv_allocation == KvAllocation::kAtLoad);
  CHECK(p->cotenant.weights == CotenantWeights::kRead);
  CHECK(ParseExperimentProfile("", "empty.toml")->cotenant.weights == CotenantWeights::kPinned);
  CHECK_FALSE(p->cotenant.prefetch);
  CHECK(p->cotenant.watchdog_s == 2.5);
  CHECK(p->cotenant.restart_delay_s == 0.0);
  CHECK(p->cotenant.context_tokens == 1024);
  CHECK(p->cotenant.kv_bytes_per_token == 1024);
  CHECK(ParseExperimentProfile("", "empty.toml")->cotenant.kv_allocation ==
        KvAllocation::kPerRequest);
  Result<ExperimentProfile> bad =
      ParseExperimentProfile("[cotenant]\nkv_allocation = \"lazy\"\n", "bad.toml");
  REQUIRE_FALSE(bad.ok());
  CHECK(Contains(bad.status().message(), "'cotenant.kv_allocation'"));
  bad = ParseExperimentProfile("[cotenant]\nweights = \"swap\"\n", "bad.toml");
  REQUIRE_FALSE(bad.ok());
  CHECK(Contains(bad.status().message(), "'cotenant.weights'"));
  // One key: the old pair is gone (weights = "pinned" is mlock + read).
  for (const char* old : {"weights_load = \"read\"", "mlock = true"}) {
    bad = ParseExperimentProfile(std::string("[cotenant]\n") + old + "\n", "bad.toml");
    CHECK_FALSE(bad.ok());
  }
  bad = ParseExperimentProfile("[cotenant]\ncontext_tokens = 100\n", "bad.toml");
  REQUIRE_FALSE(bad.ok());
  CHECK(Contains(bad.status().message(), "'cotenant.context_tokens'"));
  bad = ParseExperimentProfile("[cotenant]\nrequest_deadline_s = 120\n", "bad.toml");  // removed
  REQUIRE_FALSE(bad.ok());
  CHECK(Contains(bad.status().message(), "'cotenant.request_deadline_s'"));
}

TEST_CASE("--cotenant changes the model but keeps the planned map share") {
  Result<ExperimentProfile> loaded = LoadExperimentProfile("orin-nano-8gb");
  REQUIRE(loaded.ok());
  ExperimentProfile p = *loaded;
  const std::uint64_t share = *MapShareBytes(p.core);
  REQUIRE(ApplyModelOverride("gemma3-4b", p).ok());
  CHECK(p.core.model.name == "gemma3-4b");
  CHECK(p.core.model.weights_bytes == 3'300'000'000ULL);
  CHECK(*MapShareBytes(p.core) == share);
  Status unknown = ApplyModelOverride("gpt-9", p);
  REQUIRE_FALSE(unknown.ok());
  CHECK(Contains(unknown.message(), "gpt-9"));
}

TEST_CASE("a profile re-derived for another model gives its map share to the model's weights") {
  Result<ExperimentProfile> loaded = LoadExperimentProfile("orin-nano-8gb");
  REQUIRE(loaded.ok());
  ExperimentProfile p = *loaded;
  const std::uint64_t share = *MapShareBytes(p.core);
  const std::uint64_t weights = p.core.model.weights_bytes;
  REQUIRE(ApplyModelOverride("gemma3-4b", p, ModelShare::kRederived).ok());
  CHECK(p.core.model.name == "gemma3-4b");
  CHECK(p.core.map.map_share_bytes == 0);  // still derived, not frozen
  CHECK(*MapShareBytes(p.core) == share - (3'300'000'000ULL - weights));
}

}  // namespace
}  // namespace zm
