#include "face_contact/assembly_plan.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <set>

#include "common/error.h"

namespace visco::face_contact {
namespace {

using Eigen::Matrix4d;

// The ODL and presence of every object at one moment of the sequence.
struct World {
  std::vector<Odl> odl;
  std::vector<bool> present;
};

Matrix4d PoseOf(const Odl& odl, const std::vector<Matrix4d>& params) {
  Matrix4d m = Matrix4d::Identity();
  for (const OdlFactor& f : odl) m = m * (f.inverse ? RigidInverse(params[f.param]) : params[f.param]);
  return m;
}

std::vector<int> MovedGroup(const ApoOperation& op) {
  std::vector<int> moved{op.object};
  moved.insert(moved.end(), op.carries.begin(), op.carries.end());
  return moved;
}

bool Contains(const std::vector<int>& v, int x) { return std::find(v.begin(), v.end(), x) != v.end(); }

// §3.2.1: the manipulated object's ODL becomes (T_i); a carried object's becomes T_i·D_m⁻¹·D_s.
void ApplyOdl(World& world, const ApoOperation& op, int param) {
  if (op.kind == ApoOperation::Kind::kRemove) {
    for (int o : MovedGroup(op)) world.present[o] = false;
    return;
  }
  const Odl main_before = world.odl[op.object];
  const Odl t{{param, false}};
  for (int s : op.carries) world.odl[s] = ConcatenateOdl(t, ConcatenateOdl(InverseOdl(main_before), world.odl[s]));
  world.odl[op.object] = t;
  world.present[op.object] = true;
}

World InitialWorld(const ApoObservation& obs) {
  World world;
  world.odl.resize(obs.objects.size());
  world.present.assign(obs.objects.size(), false);
  int stable = 0;
  for (size_t o = 0; o < obs.objects.size(); ++o) {
    if (!obs.objects[o].stable) continue;
    world.odl[o] = {{stable++, false}};
    world.present[o] = true;
  }
  return world;
}

double WeightedNorm(const Matrix4d& observed, const Matrix4d& corrected, double length) {
  const Vector6d q = DeltaParameters(RigidInverse(observed) * corrected);
  return std::sqrt(q.head<3>().squaredNorm() + length * length * q.tail<3>().squaredNorm());
}

bool IsRigid(const Matrix4d& m) {
  const Eigen::Matrix3d r = m.block<3, 3>(0, 0);
  return m.allFinite() && (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-6 &&
         r.determinant() > 0 && m.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1));
}

double Diameter(const Polyhedron& model) {
  if (model.vertices.empty()) return 0;
  Eigen::Vector3d lo = model.vertices[0], hi = model.vertices[0];
  for (const auto& v : model.vertices) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  return (hi - lo).norm();
}

class Planner {
 public:
  Planner(const ApoObservation& obs, const ApoOptions& options) : obs_(obs), options_(options) {}

  ApoResult Run() {
    Validate();
    result_.mode = options_.mode;
    for (const ApoObject& o : obs_.objects) {
      if (o.stable) observed_.push_back(o.pose);
    }
    result_.stable_count = static_cast<int>(observed_.size());
    for (const ApoOperation& op : obs_.operations) observed_.push_back(op.observed);
    params_ = observed_;
    robot_params_ = observed_;
    world_ = InitialWorld(obs_);
    if (options_.mode == ApoMode::kIterative) {
      RunIterative();
    } else {
      RunAllAtOnce();
    }
    result_.observed = observed_;
    result_.corrected = params_;
    for (Relation& r : result_.relations) {
      r.observed_residue = RelationResidue(r, observed_);
      r.corrected_residue = RelationResidue(r, params_);
    }
    for (size_t i = 0; i < obs_.operations.size(); ++i) {
      const int p = Param(static_cast<int>(i));
      result_.changed.push_back(obs_.operations[i].kind == ApoOperation::Kind::kPlace &&
                                WeightedNorm(observed_[p], params_[p], options_.solver.characteristic_length) >
                                    options_.residue_threshold);
      result_.plan.push_back(Perform(static_cast<int>(i), result_.changed.back()));
    }
    return result_;
  }

 private:
  int Param(int operation) const { return result_.stable_count + operation; }
  int OperationOf(int param) const { return param - result_.stable_count; }
  const std::string& Id(int object) const { return obs_.objects[object].id; }
  std::string OpName(int i) const { return fmt::format("operations[{}] ({})", i, Id(obs_.operations[i].object)); }

  [[noreturn]] void Fail(const std::string& object, const std::string& what) const {
    throw InputError(options_.source, object, what);
  }

  void Validate() const {
    if (!(options_.solver.residue_tolerance < options_.residue_threshold)) {
      Fail("settings", "the solver's residue tolerance must be below the residue threshold");
    }
    const int n = static_cast<int>(obs_.objects.size());
    for (int o = 0; o < n; ++o) {
      const ApoObject& obj = obs_.objects[o];
      const std::string name = fmt::format("objects[{}]", o);
      if (obj.id.empty()) Fail(name, "the id is empty");
      for (int p = 0; p < o; ++p) {
        if (obs_.objects[p].id == obj.id) Fail(name, fmt::format("duplicate id '{}' (also objects[{}])", obj.id, p));
      }
      const std::string problem = CheckPolyhedron(obj.model, 1e-9 * std::max(1.0, Diameter(obj.model)));
      if (!problem.empty()) Fail(fmt::format("{} ({}).model", name, obj.id), problem);
      if (obj.stable && !IsRigid(obj.pose)) Fail(name, "the pose is not a rigid transform");
    }
    World world = InitialWorld(obs_);
    for (int i = 0; i < static_cast<int>(obs_.operations.size()); ++i) {
      const ApoOperation& op = obs_.operations[i];
      const std::string name = fmt::format("operations[{}]", i);
      if (op.object < 0 || op.object >= n) Fail(name, "unknown object");
      const std::string full = OpName(i);
      if (obs_.objects[op.object].stable) Fail(full, fmt::format("moves the stable object '{}'", Id(op.object)));
      if (op.kind == ApoOperation::Kind::kRemove && !world.present[op.object]) {
        Fail(full, fmt::format("removes '{}', which is not in the scene", Id(op.object)));
      }
      if (op.kind == ApoOperation::Kind::kPlace && !IsRigid(op.observed)) {
        Fail(full, "the observed pose is not a rigid transform");
      }
      for (size_t c = 0; c < op.carries.size(); ++c) {
        const int s = op.carries[c];
        if (s < 0 || s >= n) Fail(full, fmt::format("carries[{}] is an unknown object", c));
        if (s == op.object) Fail(full, fmt::format("'{}' carries itself", Id(s)));
        if (obs_.objects[s].stable) Fail(full, fmt::format("carries the stable object '{}'", Id(s)));
        if (!world.present[s]) Fail(full, fmt::format("carries '{}', which is not in the scene", Id(s)));
        if (!world.present[op.object]) {
          Fail(full, fmt::format("'{}' enters the scene carrying '{}': sub-assemblies form in the scene", Id(op.object),
                                 Id(s)));
        }
        for (size_t d = 0; d < c; ++d) {
          if (op.carries[d] == s) Fail(full, fmt::format("carries '{}' twice", Id(s)));
        }
      }
      if (op.contacts) {
        if (op.kind == ApoOperation::Kind::kRemove) Fail(full, "a removal forms no contacts");
        const std::vector<int> moved = MovedGroup(op);
        for (size_t c = 0; c < op.contacts->size(); ++c) {
          const GivenContact& gc = (*op.contacts)[c];
          const std::string cname = fmt::format("{}.contacts[{}]", full, c);
          if (gc.object < 0 || gc.object >= n) Fail(cname, "unknown object");
          if (gc.against < 0 || gc.against >= n) Fail(cname, "unknown 'against' object");
          if (gc.object == gc.against) {
            Fail(cname, fmt::format("a relation between '{}' and itself", Id(gc.object)));
          }
          if (!Contains(moved, gc.object)) {
            Fail(cname,
                 fmt::format("'{}' does not move in this operation, so it cannot be the face side", Id(gc.object)));
          }
          if (Contains(moved, gc.against)) {
            Fail(cname, fmt::format("'{}' moves with '{}': not a contact formed by this operation", Id(gc.against),
                                    Id(gc.object)));
          }
          if (!world.present[gc.against]) Fail(cname, fmt::format("'{}' is not in the scene", Id(gc.against)));
          const int faces = static_cast<int>(obs_.objects[gc.object].model.faces.size());
          if (gc.face < 0 || gc.face >= faces) {
            Fail(cname, fmt::format("face {} of '{}' does not exist ({} faces)", gc.face, Id(gc.object), faces));
          }
          const int against_faces = static_cast<int>(obs_.objects[gc.against].model.faces.size());
          if (gc.points.empty() && (gc.against_face < 0 || gc.against_face >= against_faces)) {
            Fail(cname, fmt::format("face {} of '{}' does not exist ({} faces)", gc.against_face, Id(gc.against),
                                    against_faces));
          }
          if (!gc.points.empty()) {
            if (gc.points.size() < 3) Fail(cname, "a face contact needs at least 3 points");
            Eigen::MatrixXd centred(3, gc.points.size());
            Eigen::Vector3d mean = Eigen::Vector3d::Zero();
            for (const auto& p : gc.points) mean += p;
            mean /= static_cast<double>(gc.points.size());
            for (size_t k = 0; k < gc.points.size(); ++k)
              centred.col(static_cast<Eigen::Index>(k)) = gc.points[k] - mean;
            const Eigen::Vector3d s = Eigen::JacobiSVD<Eigen::MatrixXd>(centred).singularValues();
            if (!(s[1] > 1e-9 * std::max(1.0, s[0]))) {
              Fail(cname,
                   "the contact points are collinear: an edge or point contact, not a face contact (the "
                   "system would be rank-deficient)");
            }
          }
        }
      }
      ApplyOdl(world, op, 0);
    }
  }

  double RelationResidue(const Relation& r, const std::vector<Matrix4d>& params) const {
    ContactProblem problem;
    problem.params = params;
    AddGroups(r, -1, problem);
    return problem.groups.empty() ? 0.0 : Residues(problem, Eigen::VectorXd()).cwiseAbs().maxCoeff();
  }

  void AddGroups(const Relation& r, int tag, ContactProblem& problem) const {
    for (const FacePatch& patch : r.patches) {
      ContactGroup g;
      g.chain = r.chain;
      g.plane = FacePlane(obs_.objects[r.face_object].model, patch.face);
      g.points = patch.points;
      g.tag = tag;
      problem.groups.push_back(std::move(g));
    }
  }

  // The covariance of a motion parameter's observation: the operation's own, else the global pose noise; none for
  // stable objects (exact).
  std::optional<PoseCovariance> ParamCovariance(int param) const {
    if (param < result_.stable_count) return std::nullopt;
    const ApoOperation& op = obs_.operations[static_cast<size_t>(OperationOf(param))];
    return op.covariance ? op.covariance : options_.pose_noise;
  }

  // Covariance of the perturbations (q_a, q_b) of a's and b's current poses (PoseOf·ΔT(q)) from the covariances of
  // the motion parameters in their ODLs (independent observations; a parameter in both ODLs correlates them, as for
  // a carried object and its carrier): Σ_p J_p Σ_p J_pᵀ, J_p by central differences. None when no parameter has one.
  std::optional<PairCovariance> PairCovarianceOf(int a, int b) const {
    const Matrix4d a_inv = RigidInverse(PoseOf(world_.odl[a], params_));
    const Matrix4d b_inv = RigidInverse(PoseOf(world_.odl[b], params_));
    std::set<int> seen;
    std::optional<PairCovariance> out;
    for (const Odl* odl : {&world_.odl[a], &world_.odl[b]}) {
      for (const OdlFactor& f : *odl) {
        const std::optional<PoseCovariance> cov = ParamCovariance(f.param);
        if (!cov || !seen.insert(f.param).second) continue;
        Eigen::Matrix<double, 12, 6> jac;
        for (int k = 0; k < 6; ++k) {
          const double h = k < 3 ? 1e-7 : 1e-6;
          Eigen::Matrix<double, 12, 1> side[2];
          for (int s = 0; s < 2; ++s) {
            Vector6d q = Vector6d::Zero();
            q[k] = s == 0 ? h : -h;
            std::vector<Matrix4d> params = params_;
            params[static_cast<size_t>(f.param)] = params_[static_cast<size_t>(f.param)] * DeltaTransform(q);
            side[s] << DeltaParameters(a_inv * PoseOf(world_.odl[a], params)),
                DeltaParameters(b_inv * PoseOf(world_.odl[b], params));
          }
          jac.col(k) = (side[0] - side[1]) / (2 * h);
        }
        if (!out) out = PairCovariance::Zero();
        *out += jac * *cov * jac.transpose();
      }
    }
    return out;
  }

  // Apply operation i to the world and the relation graph (§3.2): update ODLs, mark disappeared relations, find
  // (or take) the new relations at the current parameters.
  void ApplyOperation(int i, ApoStep& step) {
    const ApoOperation& op = obs_.operations[i];
    history_.push_back(world_);
    const std::vector<int> moved = MovedGroup(op);
    for (size_t r = 0; r < result_.relations.size(); ++r) {
      Relation& rel = result_.relations[r];
      if (rel.disappeared_by >= 0) continue;
      const bool a = Contains(moved, rel.face_object), b = Contains(moved, rel.vertex_object);
      if (op.kind == ApoOperation::Kind::kRemove ? (a || b) : (a != b)) {
        rel.disappeared_by = i;
        step.disappeared_relations.push_back(static_cast<int>(r));
      }
    }
    ApplyOdl(world_, op, Param(i));
    if (op.kind == ApoOperation::Kind::kRemove) return;
    auto add = [&](int a, int b, std::vector<FacePatch> patches, bool given) {
      if (patches.empty()) return;
      Relation rel;
      rel.formed_by = i;
      rel.face_object = a;
      rel.vertex_object = b;
      rel.chain = ConcatenateOdl(InverseOdl(world_.odl[a]), world_.odl[b]);
      rel.patches = std::move(patches);
      rel.given = given;
      step.new_relations.push_back(static_cast<int>(result_.relations.size()));
      result_.relations.push_back(std::move(rel));
    };
    if (op.contacts) {
      // Given contacts, grouped by object pair.
      std::vector<std::pair<int, int>> pairs;
      for (const GivenContact& gc : *op.contacts) {
        if (std::find(pairs.begin(), pairs.end(), std::make_pair(gc.object, gc.against)) == pairs.end()) {
          pairs.emplace_back(gc.object, gc.against);
        }
      }
      for (const auto& [a, b] : pairs) {
        std::vector<FacePatch> patches;
        for (size_t c = 0; c < op.contacts->size(); ++c) {
          const GivenContact& gc = (*op.contacts)[c];
          if (gc.object != a || gc.against != b) continue;
          FacePatch patch;
          if (gc.points.empty()) {
            std::optional<FacePatch> overlap =
                FaceOverlap(obs_.objects[a].model, PoseOf(world_.odl[a], params_), gc.face, obs_.objects[b].model,
                            PoseOf(world_.odl[b], params_), gc.against_face, 0.0);
            if (!overlap) {
              Fail(fmt::format("{}.contacts[{}]", OpName(i), c),
                   fmt::format("face {} of '{}' and face {} of '{}' do not overlap at the observed poses", gc.face,
                               Id(a), gc.against_face, Id(b)));
            }
            patch = *overlap;
          } else {
            patch.face = gc.face;
            patch.against_face = gc.against_face;
            patch.points = gc.points;
          }
          patches.push_back(std::move(patch));
        }
        add(a, b, std::move(patches), true);
      }
      return;
    }
    for (int a : moved) {
      for (int b = 0; b < static_cast<int>(obs_.objects.size()); ++b) {
        if (!world_.present[b] || Contains(moved, b)) continue;
        const std::optional<PairCovariance> covariance = PairCovarianceOf(a, b);
        add(a, b,
            FindFaceContacts(obs_.objects[a].model, PoseOf(world_.odl[a], params_), obs_.objects[b].model,
                             PoseOf(world_.odl[b], params_), options_.contact, covariance ? &*covariance : nullptr),
            false);
      }
    }
  }

  std::vector<int> Selected() const {
    std::vector<int> selected;
    for (size_t r = 0; r < result_.relations.size(); ++r) {
      if (RelationResidue(result_.relations[r], params_) > options_.residue_threshold) {
        selected.push_back(static_cast<int>(r));
      }
    }
    return selected;
  }

  // §3.3.2 steps 1–5: the motion parameters in the ODLs of the selected arcs, and every parameter connected to them
  // through arcs of the graph (disappeared ones included); stable objects are not variables. Most recent first.
  std::vector<int> Candidates(const std::vector<int>& selected) const {
    std::set<int> set;
    for (int r : selected) {
      for (const OdlFactor& f : result_.relations[r].chain) {
        if (f.param >= result_.stable_count) set.insert(f.param);
      }
    }
    for (bool grew = true; grew;) {
      grew = false;
      for (const Relation& rel : result_.relations) {
        bool touches = false;
        for (const OdlFactor& f : rel.chain) touches = touches || set.count(f.param) > 0;
        if (!touches) continue;
        for (const OdlFactor& f : rel.chain) {
          if (f.param >= result_.stable_count && set.insert(f.param).second) grew = true;
        }
      }
    }
    std::vector<int> ops;
    for (auto it = set.rbegin(); it != set.rend(); ++it) ops.push_back(OperationOf(*it));
    return ops;
  }

  ApoTrial Try(const std::vector<int>& operations) const {
    ApoTrial trial;
    trial.operations = operations;
    ContactProblem problem;
    problem.params = params_;
    for (int op : operations) problem.variables.push_back(Param(op));
    for (size_t r = 0; r < result_.relations.size(); ++r) {
      const Relation& rel = result_.relations[r];
      bool touches = false;
      for (const OdlFactor& f : rel.chain) touches = touches || Contains(problem.variables, f.param);
      if (touches) AddGroups(rel, static_cast<int>(r), problem);
    }
    trial.report = SolveContacts(problem, options_.solver);
    const std::vector<Matrix4d>& after =
        trial.report.status == SolveStatus::kConverged ? trial.report.corrected : params_;
    for (size_t r = 0; r < result_.relations.size(); ++r) {
      const double residue = RelationResidue(result_.relations[r], after);
      if (residue > trial.max_relation_residue || trial.worst_relation < 0) {
        trial.max_relation_residue = residue;
        trial.worst_relation = static_cast<int>(r);
      }
    }
    if (trial.report.status != SolveStatus::kConverged && trial.report.worst_group >= 0) {
      trial.worst_relation = problem.groups[trial.report.worst_group].tag;
      trial.max_relation_residue = trial.report.max_residue;
    }
    trial.success =
        trial.report.status == SolveStatus::kConverged && trial.max_relation_residue <= options_.residue_threshold;
    return trial;
  }

  [[noreturn]] void FailUncorrectable(const std::string& where, const ApoTrial& last) const {
    std::string ops;
    for (int op : last.operations) ops += fmt::format("{}T{}", ops.empty() ? "" : ", ", op + 1);
    std::string worst = "no relation";
    if (last.worst_relation >= 0) {
      const Relation& r = result_.relations[last.worst_relation];
      worst = fmt::format("relation R{} ('{}' against '{}', formed by operations[{}]) keeps a residue of {:.3g} m",
                          last.worst_relation + 1, Id(r.face_object), Id(r.vertex_object), r.formed_by,
                          last.max_relation_residue);
    }
    Fail(where, fmt::format("the face contacts cannot all hold even when every related operation ({}) is "
                            "corrected: {} ({})",
                            ops, worst, last.report.message));
  }

  RobotAction Perform(int j, bool corrected) const {
    const ApoOperation& op = obs_.operations[j];
    RobotAction a;
    a.operation = j;
    a.object = op.object;
    a.carries = op.carries;
    a.corrected = corrected;
    if (op.kind == ApoOperation::Kind::kRemove) {
      a.kind = RobotAction::Kind::kRemove;
    } else {
      a.kind = RobotAction::Kind::kPlace;
      a.pose = params_[Param(j)];
    }
    return a;
  }

  RobotAction Undo(int j) const {
    const ApoOperation& op = obs_.operations[j];
    const World& before = history_[j];
    RobotAction a;
    a.operation = j;
    a.object = op.object;
    a.carries = op.carries;
    a.kind = op.kind == ApoOperation::Kind::kRemove ? RobotAction::Kind::kUndoRemove : RobotAction::Kind::kUndoPlace;
    if (before.present[op.object]) a.pose = PoseOf(before.odl[op.object], robot_params_);
    return a;
  }

  void RunIterative() {
    for (int i = 0; i < static_cast<int>(obs_.operations.size()); ++i) {
      ApoStep step;
      step.operation = i;
      ApplyOperation(i, step);
      step.selected = Selected();
      if (!step.selected.empty()) {
        step.candidates = Candidates(step.selected);
        if (step.candidates.empty()) {
          Fail(OpName(i), fmt::format("relation R{} does not hold and involves no operation that can be corrected",
                                      step.selected.front() + 1));
        }
        // §4.2: the k most recent candidate operations, k = 1, 2, …
        for (size_t k = 1; k <= step.candidates.size(); ++k) {
          step.trials.push_back(Try({step.candidates.begin(), step.candidates.begin() + static_cast<long>(k)}));
          if (step.trials.back().success) {
            step.accepted = static_cast<int>(k - 1);
            break;
          }
        }
        if (step.accepted < 0) FailUncorrectable(OpName(i), step.trials.back());
        const ApoTrial& accepted = step.trials[step.accepted];
        params_ = accepted.report.corrected;
        const int first = *std::min_element(accepted.operations.begin(), accepted.operations.end());
        // Disassemble operations i−1 … first, then repeat first … i with the corrected parameters.
        for (int j = i - 1; j >= first; --j) step.robot.push_back(Undo(j));
        for (int j = first; j <= i; ++j) {
          const int p = Param(j);
          const bool changed = Contains(accepted.operations, j) &&
                               WeightedNorm(robot_params_[p], params_[p], options_.solver.characteristic_length) >
                                   options_.residue_threshold;
          step.robot.push_back(Perform(j, changed));
        }
      } else {
        step.robot.push_back(Perform(i, false));
      }
      robot_params_ = params_;
      result_.steps.push_back(std::move(step));
    }
  }

  void RunAllAtOnce() {
    ApoStep step;
    for (int i = 0; i < static_cast<int>(obs_.operations.size()); ++i) {
      ApoStep scratch;
      ApplyOperation(i, scratch);
      step.new_relations.insert(step.new_relations.end(), scratch.new_relations.begin(), scratch.new_relations.end());
      step.disappeared_relations.insert(step.disappeared_relations.end(), scratch.disappeared_relations.begin(),
                                        scratch.disappeared_relations.end());
    }
    step.selected = Selected();
    if (!step.selected.empty()) {
      step.candidates = Candidates(step.selected);
      if (step.candidates.empty()) {
        Fail("operations", fmt::format("relation R{} does not hold and involves no operation that can be corrected",
                                       step.selected.front() + 1));
      }
      step.trials.push_back(Try(step.candidates));
      if (!step.trials.back().success) FailUncorrectable("operations", step.trials.back());
      step.accepted = 0;
      params_ = step.trials.back().report.corrected;
    }
    for (int i = 0; i < static_cast<int>(obs_.operations.size()); ++i) {
      step.robot.push_back(Perform(i, !step.trials.empty() && Contains(step.trials.back().operations, i)));
    }
    result_.steps.push_back(std::move(step));
  }

  const ApoObservation& obs_;
  const ApoOptions& options_;
  ApoResult result_;
  std::vector<Matrix4d> observed_;
  std::vector<Matrix4d> params_;        // current (corrected so far) motion parameters
  std::vector<Matrix4d> robot_params_;  // what the robot has executed (iterative mode)
  World world_;
  std::vector<World> history_;  // world before each operation
};

}  // namespace

ApoResult PlanFromObservation(const ApoObservation& observation, const ApoOptions& options) {
  return Planner(observation, options).Run();
}

std::vector<std::optional<Matrix4d>> FinalPoses(const ApoObservation& observation, const ApoResult& result,
                                                bool corrected) {
  World world = InitialWorld(observation);
  for (size_t i = 0; i < observation.operations.size(); ++i) {
    ApplyOdl(world, observation.operations[i], OperationParam(result, static_cast<int>(i)));
  }
  const std::vector<Matrix4d>& params = corrected ? result.corrected : result.observed;
  std::vector<std::optional<Matrix4d>> poses(observation.objects.size());
  for (size_t o = 0; o < observation.objects.size(); ++o) {
    if (world.present[o]) poses[o] = PoseOf(world.odl[o], params);
  }
  return poses;
}

}  // namespace visco::face_contact
