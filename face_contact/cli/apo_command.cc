#include "face_contact/cli/apo_command.h"

#include <CLI/CLI.hpp>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>

#include "common/error.h"
#include "face_contact/apo_io.h"

namespace visco::face_contact {

void RegisterApoCommand(CLI::App& app) {
  struct Args {
    std::string observation;
    std::string mode;
    std::string out;
    bool text = false;
    double characteristic_length = 0;
  };
  auto args = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "apo",
      "Assembly plan from observation (Suehiro & Ikeuchi 1991): read an observed sequence of assembly operations, "
      "find the face contact relations, correct the motion parameters so that every contact holds exactly (the "
      "smallest correction; redundant degrees of freedom keep their observed values), and print the corrected "
      "parameters and the robot's assembly plan. JSON on stdout (or --out FILE, then the readable report on "
      "stdout); --text prints the readable report instead. Format: docs/apo.md. Exit 2 on bad input, including "
      "contacts that cannot all hold.");
  cmd->add_option("OBSERVATION", args->observation, "observation file (JSON, docs/apo.md)")->required();
  cmd->add_option("--mode", args->mode,
                  "iterative (after each operation, k most recent operations) or all-at-once; "
                  "overrides settings.mode")
      ->check(CLI::IsMember({"iterative", "all-at-once"}));
  cmd->add_option("--characteristic-length", args->characteristic_length,
                  "metres: a rotation of 1 rad weighs like a translation of this length (default 0.1)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--out", args->out, "write the JSON result to this file and the readable report to stdout");
  cmd->add_flag("--text", args->text, "print the readable report instead of JSON");
  cmd->callback([args] {
    ApoInput input = LoadApoObservation(args->observation);
    if (args->mode == "iterative") input.options.mode = ApoMode::kIterative;
    if (args->mode == "all-at-once") input.options.mode = ApoMode::kAllAtOnce;
    if (args->characteristic_length > 0) input.options.solver.characteristic_length = args->characteristic_length;
    const ApoResult result = PlanFromObservation(input.observation, input.options);
    if (!args->out.empty()) {
      std::ofstream file(args->out);
      if (!file) throw InputError(args->out, "", "cannot be written");
      file << ApoResultJson(input, result);
      if (!file) throw JobFailed(args->out + ": write failed");
      std::cout << ApoResultText(input, result);
    } else if (args->text) {
      std::cout << ApoResultText(input, result);
    } else {
      std::cout << ApoResultJson(input, result);
    }
  });
}

}  // namespace visco::face_contact
