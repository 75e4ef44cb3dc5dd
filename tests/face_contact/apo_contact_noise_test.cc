// Contacts found from noisy poses: random assemblies of boxes on a table (stacked, side by side touching,
// side by side 2–10 mm apart), observed with seeded Gaussian pose noise (object frame). The face pairs found are
// compared with the true ones (found at the true poses with zero tolerance): missed true relations and false ones,
// with the fixed default thresholds (3 mm, 3°) and with thresholds derived from the poses' covariance
// (ContactThresholds, FindFaceContacts' covariance), at a real observation's noise (per object 1–3 mm, 0.5–2°) and
// at a precise one (0.1–0.3 mm, 0.05–0.2°). The tests fail if the thresholds are fixed again. Figures: docs/apo.md,
// "Thresholds from the pose noise" (VISCO_CONTACT_SWEEP=1 adds other false-miss probabilities and a mixed noise).

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <random>
#include <set>
#include <string>
#include <tuple>

#include "face_contact/assembly_plan.h"
#include "face_contact/polyhedron.h"
#include "tests/face_contact/apo_examples.h"

namespace visco::face_contact {
namespace {

using Eigen::Matrix4d;
using Eigen::Vector3d;

struct NoisyScene {
  std::vector<Polyhedron> models;   // 0: the table
  std::vector<Matrix4d> truth;      // true poses
  std::vector<Matrix4d> observed;   // noisy poses (the table exact)
  std::vector<PoseCovariance> cov;  // the noise's covariance (zero for the table)
};

// Per object: translation stddev in [t_lo, t_hi] metres, rotation stddev in [r_lo, r_hi] degrees.
struct NoiseRange {
  double t_lo, t_hi, r_lo, r_hi;
};
constexpr NoiseRange kReal{0.001, 0.003, 0.5, 2.0};  // a real observation

NoisyScene MakeScene(unsigned seed, int boxes, const NoiseRange& range = kReal) {
  std::mt19937_64 rng(seed);
  auto u = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  std::normal_distribution<double> n01;
  NoisyScene s;
  s.models.push_back(MakeBox({2, 2, 0.05}));
  s.truth.push_back(testing::Pose(0, 0, -0.05));
  struct Column {
    int top;
    Vector3d size;
    bool stackable, side_free;
  };
  std::vector<Column> columns;
  int cell = 0;
  for (int i = 0; i < boxes; ++i) {
    Vector3d size(u(0.03, 0.08), u(0.03, 0.08), u(0.02, 0.06));
    const double choice = u(0, 1);
    std::vector<int> stackable, side_free;
    for (size_t c = 0; c < columns.size(); ++c) {
      if (columns[c].stackable) stackable.push_back(static_cast<int>(c));
      if (columns[c].side_free) side_free.push_back(static_cast<int>(c));
    }
    Matrix4d truth;
    const int index = static_cast<int>(s.models.size());
    if (choice < 0.35 && !stackable.empty()) {
      Column& col = columns[static_cast<size_t>(stackable[static_cast<size_t>(u(0, 1) * stackable.size())])];
      truth = s.truth[static_cast<size_t>(col.top)] *
              testing::Pose(u(-0.008, 0.008), u(-0.008, 0.008), col.size.z(), u(-30, 30));
      col.top = index;
      col.size = size;
      col.side_free = false;
    } else if (choice < 0.75 && !side_free.empty()) {
      Column& col = columns[static_cast<size_t>(side_free[static_cast<size_t>(u(0, 1) * side_free.size())])];
      // Touching, or seen close but apart: a gap of 2–10 mm.
      const double gap = u(0, 1) < 0.5 ? 0.0 : u(0.002, 0.010);
      size.z() = std::min(size.z(), col.size.z() - 0.005);
      size.y() = std::max(size.y(), 0.03);
      truth = s.truth[static_cast<size_t>(col.top)] *
              testing::Pose(col.size.x() / 2 + size.x() / 2 + gap, u(-0.005, 0.005), 0);
      col.side_free = false;
      columns.push_back({index, size, false, false});
    } else {
      truth = testing::Pose((cell % 5) * 0.3 - 0.6, (cell / 5) * 0.3 - 0.6, 0, u(-30, 30));
      ++cell;
      columns.push_back({index, size, true, true});
    }
    s.models.push_back(MakeBox(size));
    s.truth.push_back(truth);
  }
  s.observed = s.truth;
  s.cov.assign(s.truth.size(), PoseCovariance::Zero());
  for (size_t i = 1; i < s.truth.size(); ++i) {
    const double st = u(range.t_lo, range.t_hi), sr = u(range.r_lo, range.r_hi) * std::numbers::pi / 180;
    Vector6d q;
    for (int k = 0; k < 6; ++k) q[k] = (k < 3 ? st : sr) * n01(rng);
    s.observed[i] = s.truth[i] * DeltaTransform(q);
    s.cov[i].diagonal() << st * st, st * st, st * st, sr * sr, sr * sr, sr * sr;
  }
  return s;
}

using Key = std::tuple<int, int, int, int>;  // object, face, against, against_face

std::set<Key> Find(const NoisyScene& s, const std::vector<Matrix4d>& poses, const ContactThresholds& t, bool derived) {
  std::set<Key> out;
  for (int a = 1; a < static_cast<int>(poses.size()); ++a) {
    for (int b = 0; b < a; ++b) {
      PairCovariance cov = PairCovariance::Zero();
      cov.topLeftCorner<6, 6>() = s.cov[static_cast<size_t>(a)];
      cov.bottomRightCorner<6, 6>() = s.cov[static_cast<size_t>(b)];
      for (const FacePatch& p : FindFaceContacts(s.models[static_cast<size_t>(a)], poses[static_cast<size_t>(a)],
                                                 s.models[static_cast<size_t>(b)], poses[static_cast<size_t>(b)], t,
                                                 derived ? &cov : nullptr)) {
        out.emplace(a, p.face, b, p.against_face);
      }
    }
  }
  return out;
}

struct Counts {
  int truth = 0, missed = 0, false_found = 0;
  int false_by_gap[5] = {0, 0, 0, 0, 0};  // true gap ≤ 5 mm, 5–10 mm, 10–25 mm, > 25 mm; faces not overlapping
};

void Tally(const NoisyScene& s, const std::set<Key>& truth, const std::set<Key>& found, Counts& c) {
  c.truth += static_cast<int>(truth.size());
  for (const Key& k : truth) c.missed += found.count(k) ? 0 : 1;
  for (const Key& k : found) {
    if (truth.count(k)) continue;
    ++c.false_found;
    const auto [a, fa, b, fb] = k;
    const auto at_truth = FaceOverlap(s.models[static_cast<size_t>(a)], s.truth[static_cast<size_t>(a)], fa,
                                      s.models[static_cast<size_t>(b)], s.truth[static_cast<size_t>(b)], fb, 0.0);
    const double gap = at_truth ? at_truth->max_gap : -1.0;
    ++c.false_by_gap[gap < 0 ? 4 : gap <= 0.005 ? 0 : gap <= 0.010 ? 1 : gap <= 0.025 ? 2 : 3];
  }
}

#if defined(__SANITIZE_ADDRESS__)
constexpr unsigned kSeeds = 120;  // the first 120 seeds: 8 false relations of the fixed thresholds with precise poses
#else
constexpr unsigned kSeeds = 400;
#endif

std::string Line(const Counts& c) {
  char text[200];
  std::snprintf(text, sizeof text,
                "missed %d, false %d (true gap <= 5 mm %d, 5-10 mm %d, 10-25 mm %d, farther %d; faces not "
                "overlapping at the truth %d)",
                c.missed, c.false_found, c.false_by_gap[0], c.false_by_gap[1], c.false_by_gap[2], c.false_by_gap[3],
                c.false_by_gap[4]);
  return text;
}

// Old (fixed defaults) and new (derived) counts over kSeeds scenes of 6 boxes with noise in `range`.
std::pair<Counts, Counts> Compare(const NoiseRange& range, const ContactThresholds& derived = {}) {
  ContactThresholds exact;
  exact.distance = 1e-9;
  exact.angle_deg = 1e-6;
  Counts old_counts, new_counts;
  for (unsigned seed = 1; seed <= kSeeds; ++seed) {
    const NoisyScene s = MakeScene(seed, 6, range);
    const std::set<Key> truth = Find(s, s.truth, exact, false);
    Tally(s, truth, Find(s, s.observed, ContactThresholds{}, false), old_counts);
    Tally(s, truth, Find(s, s.observed, derived, true), new_counts);
  }
  std::printf(
      "noise %g-%g mm, %g-%g deg; %u scenes, %d true face contacts:\n  fixed 3 mm / 3 deg: %s\n  derived "
      "(false-miss probability %g): %s\n",
      1e3 * range.t_lo, 1e3 * range.t_hi, range.r_lo, range.r_hi, kSeeds, old_counts.truth, Line(old_counts).c_str(),
      derived.false_miss_probability, Line(new_counts).c_str());
  return {old_counts, new_counts};
}

// The promise of the noise model: a true contact is missed at most with the false-miss probability (first order;
// an overlap that noise makes thinner than min_width is also missed, by both rules). 3 alpha for the sample.
int Promise(const Counts& c) { return static_cast<int>(3 * ContactThresholds{}.false_miss_probability * c.truth) + 3; }

// A real observation (1–3 mm, 0.5–2°): the fixed thresholds miss a large share of the true contacts; the derived
// ones keep their promise. Faces seen close but apart within what the noise can tell from zero (a 5 mm gap seen with
// 3 mm per pose) are called touching more often than by the fixed thresholds (which reject them, as they reject
// the true contacts, by chance): no threshold on these observations separates them. None farther than 25 mm.
TEST(ContactNoise, RealObservationNoiseDerivedThresholdsMissFewerTrueRelations) {
  const auto [old_counts, new_counts] = Compare(kReal);
  ASSERT_GT(old_counts.truth, 5 * static_cast<int>(kSeeds));
  EXPECT_LE(new_counts.missed, Promise(new_counts));
  EXPECT_LT(10 * new_counts.missed, old_counts.missed);
  EXPECT_EQ(new_counts.false_by_gap[3], 0);
  EXPECT_EQ(old_counts.false_by_gap[3], 0);
  if (std::getenv("VISCO_CONTACT_SWEEP")) {
    for (double alpha : {1e-2, 0.05, 0.2, 0.45}) {
      ContactThresholds d;
      d.false_miss_probability = alpha;
      Compare(kReal, d);
    }
    Compare({1e-4, 3e-3, 0.05, 2});
  }
}

// A precise observation (0.1–0.3 mm, 0.05–0.2°, several tags): the fixed 3 mm calls faces 2–3 mm apart touching;
// the derived thresholds do not, and still keep their promise on the true contacts.
TEST(ContactNoise, PreciseObservationsDerivedThresholdsFindNoFalseRelations) {
  const auto [old_counts, new_counts] = Compare({1e-4, 3e-4, 0.05, 0.2});
  EXPECT_LE(new_counts.missed, Promise(new_counts));
  EXPECT_GE(old_counts.false_found, static_cast<int>(kSeeds) / 24);  // 28 in 400 scenes, 8 in the first 120
  EXPECT_LE(new_counts.false_found, 2);
}

// `visco apo` finds its relations with the same derived thresholds: each operation's covariance (or the global
// pose_noise) reaches FindFaceContacts through the ODLs. All at once, the relations are found at the observed poses,
// so they are exactly the face pairs found directly; without covariance, those of the fixed thresholds.
TEST(ContactNoise, ApoFindsTheRelationsOfTheDerivedThresholds) {
  int differing = 0;
  for (unsigned seed = 1; seed <= 12; ++seed) {
    const NoisyScene s = MakeScene(seed, 6);
    ApoObservation obs;
    testing::AddObject(obs, "table", s.models[0], true, s.truth[0]);
    for (size_t i = 1; i < s.models.size(); ++i) {
      ApoOperation op;
      op.object = testing::AddObject(obs, "box" + std::to_string(i), s.models[i]);
      op.observed = s.observed[i];
      op.covariance = s.cov[i];
      obs.operations.push_back(op);
    }
    ApoOptions options;
    options.mode = ApoMode::kAllAtOnce;
    for (bool derived : {true, false}) {
      SCOPED_TRACE(::testing::Message() << "seed " << seed << (derived ? " derived" : " fixed"));
      ApoObservation o = obs;
      if (!derived) {
        for (ApoOperation& op : o.operations) op.covariance.reset();
      }
      std::set<Key> found;
      try {
        const ApoResult result = PlanFromObservation(o, options);
        for (const Relation& r : result.relations) {
          for (const FacePatch& p : r.patches) found.emplace(r.face_object, p.face, r.vertex_object, p.against_face);
        }
      } catch (const std::exception& e) {
        continue;  // contacts that cannot all hold (a false one): the relations are not reported
      }
      const std::set<Key> direct = Find(s, s.observed, ContactThresholds{}, derived);
      EXPECT_EQ(found, direct);
      if (derived) differing += found != Find(s, s.observed, ContactThresholds{}, false) ? 1 : 0;
    }
  }
  EXPECT_GT(differing, 3);  // the covariance changes what apo finds
}

}  // namespace
}  // namespace visco::face_contact
