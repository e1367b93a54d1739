// Repeats (harness/repeats.h): the interleaved order of a bench's runs, the statistics over a
// cell's repeats (known values), the representative repeat, and a statistic as a table cell.
#include "harness/repeats.h"

#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <vector>

namespace zm {
namespace {

TEST_CASE("cells run interleaved: every cell's repeat r before any cell's repeat r + 1") {
  const std::vector<CellRepeat> order = InterleavedOrder(2, 3);
  // A B A B A B, not A A A B B B.
  const std::vector<CellRepeat> want = {{0, 0}, {1, 0}, {0, 1}, {1, 1}, {0, 2}, {1, 2}};
  CHECK(order == want);
  const std::vector<CellRepeat> three = InterleavedOrder(3, 2);
  REQUIRE(three.size() == 6);
  CHECK(three[2] == CellRepeat{2, 0});
  CHECK(three[3] == CellRepeat{0, 1});
  CHECK(InterleavedOrder(4, 1).size() == 4);
  CHECK(InterleavedOrder(0, 5).empty());
  CHECK(InterleavedOrder(5, 0).empty());
}

TEST_CASE("Student's t quantile: the table, and the expansion beyond it") {
  CHECK(std::isnan(StudentT975(0)));
  CHECK(StudentT975(1) == doctest::Approx(12.706205));
  CHECK(StudentT975(4) == doctest::Approx(2.776445));
  CHECK(StudentT975(30) == doctest::Approx(2.042272));
  CHECK(StudentT975(31) == doctest::Approx(2.039513).epsilon(1e-5));   // scipy
  CHECK(StudentT975(100) == doctest::Approx(1.983972).epsilon(1e-5));  // scipy
}

TEST_CASE("mean and 95 % confidence interval of known values") {
  const std::vector<double> v = {1, 2, 3, 4, 5};
  const RepeatStats s = SummarizeRepeats(v);
  CHECK(s.n == 5);
  CHECK(s.mean == doctest::Approx(3.0));
  CHECK(s.sd == doctest::Approx(std::sqrt(2.5)));
  // t(0.975, 4) x sd / sqrt(5) = 2.776445 x 1.581139 / 2.236068 = 1.963243
  CHECK(s.ci95 == doctest::Approx(1.963243).epsilon(1e-6));
  CHECK(s.median == doctest::Approx(3.0).epsilon(0.005));  // StreamingStats: within 0.5 %
  CHECK(s.min == 1.0);
  CHECK(s.max == 5.0);

  const std::vector<double> two = {10, 12};
  const RepeatStats t = SummarizeRepeats(two);
  CHECK(t.mean == doctest::Approx(11.0));
  CHECK(t.ci95 == doctest::Approx(12.706205 * std::sqrt(2.0) / std::sqrt(2.0)));  // 12.71

  const std::vector<double> one = {7.5};
  const RepeatStats o = SummarizeRepeats(one);
  CHECK(o.n == 1);
  CHECK(o.mean == 7.5);
  CHECK(o.ci95 == 0.0);  // one run: no interval

  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<double> gaps = {nan, 4.0, nan, 6.0};  // a run without the value
  const RepeatStats g = SummarizeRepeats(gaps);
  CHECK(g.n == 2);
  CHECK(g.mean == doctest::Approx(5.0));
  CHECK(SummarizeRepeats(std::vector<double>{}).n == 0);
}

TEST_CASE("statistics of every numeric key of the summaries, by JSON pointer") {
  std::vector<nlohmann::json> runs = {
      {{"update_rate_hz", 0.9},
       {"tick_ms", {{"mean", 10.0}}},
       {"policy", "basic"},
       {"cotenant", {{"tokens_per_s", nullptr}, {"per_request", {1, 2, 3}}}},
       {"ok", true}},
      {{"update_rate_hz", 1.0},
       {"tick_ms", {{"mean", 14.0}}},
       {"policy", "basic"},
       {"cotenant", {{"tokens_per_s", 3.0}}},
       {"ok", false}},
  };
  const nlohmann::json st = StatsOfSummaries(runs);
  CHECK(st["/update_rate_hz"]["n"] == 2);
  CHECK(st["/update_rate_hz"]["mean"].get<double>() == doctest::Approx(0.95));
  CHECK(st["/tick_ms/mean"]["mean"].get<double>() == doctest::Approx(12.0));
  CHECK(st["/tick_ms/mean"]["values"] == nlohmann::json::array({10.0, 14.0}));
  CHECK(st["/cotenant/tokens_per_s"]["n"] == 1);  // null in the first run
  CHECK_FALSE(st.contains("/policy"));            // not a number
  CHECK_FALSE(st.contains("/ok"));                // a boolean is not a number
  CHECK_FALSE(st.contains("/cotenant/per_request"));
}

TEST_CASE("the representative repeat is the one nearest the median") {
  CHECK(RepresentativeRepeat(std::vector<double>{30.0, 10.0, 20.0}) == 2);
  CHECK(RepresentativeRepeat(std::vector<double>{5.0}) == 0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  CHECK(RepresentativeRepeat(std::vector<double>{nan, 8.0, 9.0, 100.0}) == 2);
  CHECK(RepresentativeRepeat(std::vector<double>{}) == 0);
}

TEST_CASE("a statistic as a table cell: n = 1 says so, n = 3 shows the interval") {
  const nlohmann::json three = ToJson(SummarizeRepeats(std::vector<double>{1, 2, 3}));
  // mean 2, sd 1, t(0.975, 2) = 4.302653: half-width 2.484
  CHECK(FormatStat(three, 2) == "2.00 ± 2.48");
  CHECK(FormatStat(three, 1, 1000.0) == "2000.0 ± 2484.1");
  CHECK(FormatStat(three, 2, 1.0, 5) == "2.00 ± 2.48 (n = 3)");
  const nlohmann::json one = ToJson(SummarizeRepeats(std::vector<double>{0.5}));
  CHECK(FormatStat(one, 3) == "0.500 (1 run)");
  CHECK(FormatStat(one, 3, 1.0, 3) == "0.500 (1 run)");
  CHECK(FormatStat(nlohmann::json(), 2) == "–");
  CHECK(FormatStat(ToJson(SummarizeRepeats(std::vector<double>{})), 2) == "–");
}

TEST_CASE("a statistic in the paper's form: thousands grouped, n stated by the header") {
  const StatStyle paper{.group_thousands = true, .n_in_header = true};
  const nlohmann::json faults = {{"n", 3}, {"mean", 11419.2}, {"ci95", 1332.4}};
  CHECK(FormatStat(faults, 0, 1.0, 3, paper) == "11,419 ± 1,332");
  CHECK(FormatStat(faults, 0, 1.0, 3) == "11419 ± 1332");
  CHECK(FormatStat(faults, 1, 1.0, 5, paper) == "11,419.2 ± 1,332.4 (n = 3)");
  const nlohmann::json one = {{"n", 1}, {"mean", 0.5}, {"ci95", 0.0}};
  CHECK(FormatStat(one, 3, 1.0, 1, paper) == "0.500");          // the header says "1 run"
  CHECK(FormatStat(one, 3, 1.0, 3, paper) == "0.500 (1 run)");  // one run of three
  CHECK(FormatStat(one, 3, 1.0, 1) == "0.500 (1 run)");
  CHECK(FormatNumber(5064.87, 2, true) == "5,064.87");
  CHECK(FormatNumber(-1234567.0, 0, true) == "-1,234,567");
  CHECK(FormatNumber(999.0, 0, true) == "999");
  CHECK(FormatNumber(std::nan(""), 2, true) == "–");
}

}  // namespace
}  // namespace zm
