// `zonemap vocab MAP.db`: trains the map's visual vocabulary (hierarchical k-majority over the
// keyframes' ORB descriptors, lib/localization/vocabulary.h) from the map's own keyframes and
// stores it in the map database (schema version 2), replacing any earlier one.
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.h"
#include "localization/map_vocabulary.h"

namespace zm::app {

void AddVocabCommand(CLI::App& app, CommandContext& ctx) {
  struct Opts {
    std::string map;
    MapVocabularyOptions o;
    bool json = false;
  };
  auto opts = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand(
      "vocab", "Train the map's visual vocabulary from its keyframes and store it in the map");
  cmd->add_option("MAP", opts->map, "zonemap map database (modified in place)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("-k,--branching", opts->o.vocabulary.branching, "children per node (k)")
      ->capture_default_str();
  cmd->add_option("-L,--depth", opts->o.vocabulary.depth, "levels of the tree (L): at most k^L words")
      ->capture_default_str();
  cmd->add_option("--iterations", opts->o.vocabulary.max_iterations,
                  "Lloyd iterations per split at most")
      ->capture_default_str();
  cmd->add_option("--seed", opts->o.vocabulary.seed, "k-means++ seed (same seed and map, same vocabulary)")
      ->capture_default_str();
  cmd->add_option("--word-features", opts->o.word_features,
                  "descriptors per keyframe, strongest first (RTAB-Map's Kp/MaxFeatures)")
      ->capture_default_str();
  cmd->add_option("--max-keyframes", opts->o.max_keyframes,
                  "train on this many keyframes spread over the map (0 = every keyframe)")
      ->capture_default_str();
  cmd->add_flag("--json", opts->json, "print the report as JSON");
  cmd->callback([opts, &ctx] {
    auto r = TrainAndStoreMapVocabulary(opts->map, opts->o);
    if (!r.ok()) {
      ctx.Fail("vocab", r.status());
      return;
    }
    if (opts->json) {
      const nlohmann::json j = {{"map", opts->map},
                                {"branching", opts->o.vocabulary.branching},
                                {"depth", opts->o.vocabulary.depth},
                                {"seed", opts->o.vocabulary.seed},
                                {"word_features", opts->o.word_features},
                                {"words", r->words},
                                {"nodes", r->nodes},
                                {"memory_bytes", r->memory_bytes},
                                {"blob_bytes", r->blob_bytes},
                                {"map_keyframes", r->map_keyframes},
                                {"training_keyframes", r->training_keyframes},
                                {"keyframes_without_features", r->keyframes_without_features},
                                {"training_descriptors", r->training_descriptors},
                                {"read_ms", r->read_ms},
                                {"train_ms", r->train_ms}};
      std::printf("%s\n", j.dump(2).c_str());
      return;
    }
    std::printf("vocab: %s: %u words, %u nodes (k %u, L %u, seed %llu), %.2f MB in memory, %llu "
                "bytes stored\n",
                opts->map.c_str(), r->words, r->nodes, opts->o.vocabulary.branching,
                opts->o.vocabulary.depth,
                static_cast<unsigned long long>(opts->o.vocabulary.seed),
                static_cast<double>(r->memory_bytes) / 1e6,
                static_cast<unsigned long long>(r->blob_bytes));
    std::printf("  trained on %u of %u keyframes (%u without features), %llu descriptors (at most "
                "%u per keyframe)\n",
                r->training_keyframes, r->map_keyframes, r->keyframes_without_features,
                static_cast<unsigned long long>(r->training_descriptors), opts->o.word_features);
    std::printf("  read %.1f ms, train %.1f ms\n", r->read_ms, r->train_ms);
  });
}

}  // namespace zm::app
