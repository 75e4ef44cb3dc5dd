// The observation file (docs/apo.md): the example files in data/apo/ give the paper's trials; bad input is
// rejected with the file, the object and what is wrong.

#include "face_contact/apo_io.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "common/error.h"

namespace visco::face_contact {
namespace {

std::vector<std::vector<int>> Trials(const ApoStep& step) {
  std::vector<std::vector<int>> out;
  for (const ApoTrial& t : step.trials) {
    std::vector<int> ops;
    for (int o : t.operations) ops.push_back(o + 1);
    out.push_back(ops);
  }
  return out;
}

TEST(ApoFiles, ExamplesGiveThePapersTrials) {
  struct Case {
    const char* file;
    std::vector<std::vector<int>> last;
  };
  for (const Case& c : {Case{"data/apo/castles_stick.json", {{3}, {3, 2}}},
                        Case{"data/apo/sub_assembly.json", {{5}, {5, 4}, {5, 4, 3}, {5, 4, 3, 2}}},
                        Case{"data/apo/disappeared_relation.json", {{5}, {5, 3}, {5, 3, 2}}}}) {
    SCOPED_TRACE(c.file);
    const ApoInput input = LoadApoObservation(c.file);
    const ApoResult result = PlanFromObservation(input.observation, input.options);
    EXPECT_EQ(Trials(result.steps.back()), c.last);
    for (const Relation& r : result.relations) EXPECT_LE(r.corrected_residue, 1e-9);
    const nlohmann::json json = nlohmann::json::parse(ApoResultJson(input, result));
    EXPECT_EQ(json["mode"], "iterative");
    EXPECT_EQ(json["steps"].back()["corrected_operations"], nlohmann::json(c.last.back()));
    EXPECT_FALSE(json["plan"].empty());
    const std::string text = ApoResultText(input, result);
    EXPECT_NE(text.find("succeeds"), std::string::npos);
  }
}

const char* kGood = R"({
  "objects": [
    {"id": "table", "stable": true, "model": {"box": [1, 1, 0.05]}, "pose": {"t": [0, 0, -0.05], "rxyz_deg": [0, 0, 0]}},
    {"id": "block", "model": {"box": [0.1, 0.1, 0.05]}}
  ],
  "operations": [{"object": "block", "pose": {"t": [0, 0, 0.001], "rxyz_deg": [0.5, 0, 10]}}]
})";

std::string Error(const std::string& text) {
  try {
    const ApoInput input = ParseApoObservation(text, "obs.json");
    PlanFromObservation(input.observation, input.options);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

TEST(ApoFiles, GoodFileRuns) { EXPECT_EQ(Error(kGood), ""); }

TEST(ApoFiles, BadInputIsNamed) {
  EXPECT_NE(Error("{").find("obs.json: not valid JSON"), std::string::npos) << Error("{");
  EXPECT_NE(Error(Replace(kGood, "\"object\": \"block\"", "\"object\": \"blok\""))
                .find("obs.json: operations[0].object: unknown object id 'blok'"),
            std::string::npos);
  EXPECT_NE(Error(Replace(kGood, "\"rxyz_deg\": [0.5, 0, 10]", "\"R\": [[1, 0, 0], [0, 1, 0], [0, 0, 2]]"))
                .find("operations[0].pose.R: is not a rotation"),
            std::string::npos);
  EXPECT_NE(Error(Replace(kGood, "\"object\": \"block\"", "\"object\": \"table\""))
                .find("operations[0] (table): moves the stable object 'table'"),
            std::string::npos);
  EXPECT_NE(Error(Replace(kGood, "\"stable\": true,", "\"stable\": true, \"colour\": 1,"))
                .find("objects[0]: unknown field 'colour'"),
            std::string::npos);
  // A non-planar face.
  const std::string bent = Replace(kGood, "{\"box\": [0.1, 0.1, 0.05]}",
                                   R"({"vertices": [[0,0,0],[1,0,0],[1,1,0.01],[0,1,0],[0,0,1],[1,0,1],[1,1,1],[0,1,1]],
          "faces": [[0,3,2,1],[4,5,6,7],[0,1,5,4],[1,2,6,5],[2,3,7,6],[3,0,4,7]]})");
  EXPECT_NE(Error(bent).find("objects[1] (block).model: face 0 is not planar: vertex"), std::string::npos)
      << Error(bent);
  // A relation between an object and itself.
  const std::string self = Replace(
      kGood, "\"rxyz_deg\": [0.5, 0, 10]}}",
      R"("rxyz_deg": [0.5, 0, 10]}, "contacts": [{"object": "block", "face": 0, "against": "block", "against_face": 1}]})");
  EXPECT_NE(Error(self).find("operations[0] (block).contacts[0]: a relation between 'block' and itself"),
            std::string::npos)
      << Error(self);
  // Collinear given points: not a face contact (rank-deficient).
  const std::string line =
      Replace(kGood, "\"rxyz_deg\": [0.5, 0, 10]}}",
              R"("rxyz_deg": [0.5, 0, 10]}, "contacts": [{"object": "block", "face": 0, "against": "table",
          "points": [[0, 0, 0.05], [0.01, 0, 0.05], [0.02, 0, 0.05]]}]})");
  EXPECT_NE(Error(line).find("collinear"), std::string::npos) << Error(line);
  // Contacts that cannot all hold: the block given against the table top and against the table's bottom face.
  const std::string impossible = Replace(kGood, "\"rxyz_deg\": [0.5, 0, 10]}}",
                                         R"("rxyz_deg": [0.5, 0, 10]}, "contacts": [
          {"object": "block", "face": 0, "against": "table", "points": [[0, 0, 0.05], [0.01, 0, 0.05], [0, 0.01, 0.05]]},
          {"object": "block", "face": 1, "against": "table", "points": [[0, 0, 0.05], [0.01, 0, 0.05], [0, 0.01, 0.05]]}]})");
  EXPECT_NE(Error(impossible).find("cannot all hold even when every related operation (T1) is corrected"),
            std::string::npos)
      << Error(impossible);
}

// Thresholds from the pose noise (docs/apo.md): the block seen 5 mm above the table. With the fixed 3 mm the contact
// is missed; with a pose noise of 3 mm (global, per operation, or as a covariance) it is within what the noise
// explains and found; with 0.3 mm it is not.
TEST(ApoFiles, PoseNoiseDerivesTheThresholds) {
  const std::string raised = Replace(kGood, "\"t\": [0, 0, 0.001]", "\"t\": [0, 0, 0.005]");
  auto relations = [](const std::string& text) {
    const ApoInput input = ParseApoObservation(text, "obs.json");
    return PlanFromObservation(input.observation, input.options).relations.size();
  };
  EXPECT_EQ(relations(raised), 0u);
  const std::string global = Replace(raised, "\"objects\"", R"("settings": {"pose_noise": {"t": 0.003, "rxyz_deg": 1}},
  "objects")");
  EXPECT_EQ(relations(global), 1u);
  EXPECT_EQ(relations(Replace(global, "\"t\": 0.003", "\"t\": 0.0003")), 0u);
  EXPECT_NE(Error(Replace(global, "\"rxyz_deg\": 1}", "\"rxyz_deg\": 1}, \"false_miss_probability\": 0.7"))
                .find("settings.false_miss_probability: must be below 0.5"),
            std::string::npos);
  const std::string per_op =
      Replace(raised, "\"rxyz_deg\": [0.5, 0, 10]}}",
              R"("rxyz_deg": [0.5, 0, 10]}, "pose_noise": {"t": [0.003, 0.003, 0.003], "rxyz_deg": 1}})");
  EXPECT_EQ(relations(per_op), 1u);
  const std::string cov =
      Replace(raised, "\"rxyz_deg\": [0.5, 0, 10]}}", R"("rxyz_deg": [0.5, 0, 10]}, "pose_covariance":
      [[9e-6, 0, 0, 0, 0, 0], [0, 9e-6, 0, 0, 0, 0], [0, 0, 9e-6, 0, 0, 0], [0, 0, 0, 3e-4, 0, 0], [0, 0, 0, 0, 3e-4, 0],
       [0, 0, 0, 0, 0, 3e-4]]})");
  EXPECT_EQ(relations(cov), 1u);
  // Bad noise is named.
  EXPECT_NE(Error(Replace(global, "\"t\": 0.003", "\"t\": -0.003")).find("settings.pose_noise.t: standard deviations"),
            std::string::npos);
  EXPECT_NE(Error(Replace(cov, "[0, 9e-6, 0, 0, 0, 0]", "[1e-6, 9e-6, 0, 0, 0, 0]"))
                .find("operations[0].pose_covariance: must be symmetric"),
            std::string::npos);
  EXPECT_NE(Error(Replace(cov, "[0, 0, 9e-6, 0, 0, 0]", "[0, 0, -9e-6, 0, 0, 0]"))
                .find("operations[0].pose_covariance: must be positive semi-definite"),
            std::string::npos);
  EXPECT_NE(Error(Replace(per_op, "\"pose_noise\"", "\"pose_covariance\": [], \"pose_noise\""))
                .find("operations[0]: give 'pose_noise' or 'pose_covariance', not both"),
            std::string::npos);
  EXPECT_NE(Error(Replace(global, "\"pose_noise\": {\"t\": 0.003, \"rxyz_deg\": 1}", "\"pose_noise\": {\"t\": 0.003}"))
                .find("settings.pose_noise: needs 't' and 'rxyz_deg'"),
            std::string::npos);
}

}  // namespace
}  // namespace visco::face_contact
