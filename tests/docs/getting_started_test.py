#!/usr/bin/env python3
"""docs/getting_started.md's examples, run as written, so that the page cannot drift from the program.

usage: getting_started_test.py SOURCE_DIR BIN_DIR

In a fresh working directory that holds the page's own scene (its JSON block named "my_scene") and links to the
clone's data/ and tests/ (the page's commands name them relative to the clone):
- every ```text block made of `$ COMMAND` lines: each command runs (`visco` is BIN_DIR's) and what the page shows
  under it appears in its output, line by line and in order (a line ending in "..." is a prefix);
- every line of a ```sh block that runs one of the quick planner commands (vcrays, plan, backproject, critical) or
  `visco sim ... --write-world` runs and exits 0;
- the words about the plans: the steps of my_plan.json (θ of each step, the contact feature) and the one step of the
  default slot scene (θ and the CVC ray it complies to), as the page states them.
The demo's list of output files is checked against a real demo by tests/app/scripts_demo_test.sh. Not run here: the
minute-long run against the simulator, lcm-spy (needs a display) and the demo itself.
"""
import json
import os
import re
import shlex
import subprocess
import sys
import tempfile

src, bin_dir = (os.path.abspath(a) for a in sys.argv[1:3])
page_path = os.path.join(src, "docs", "getting_started.md")
page = open(page_path, encoding="utf-8").read()
failures = []


def fail(what):
    failures.append(what)
    print("FAIL: " + what)


blocks = re.findall(r"^```(\w*)\n(.*?)^```", page, re.S | re.M)
work = tempfile.mkdtemp(prefix="visco-docs-")
for name in ("data", "tests"):
    os.symlink(os.path.join(src, name), os.path.join(work, name))
env = dict(os.environ, PATH=bin_dir + os.pathsep + os.environ["PATH"])

scene = [body for lang, body in blocks if lang == "json" and '"name": "my_scene"' in body]
if len(scene) != 1:
    fail("the page has %d JSON blocks of the scene my_scene (expected 1)" % len(scene))
else:
    open(os.path.join(work, "my_scene.json"), "w").write(scene[0])


def run(command, timeout=300):
    r = subprocess.run(command, shell=True, cwd=work, env=env, capture_output=True, text=True, timeout=timeout)
    return r.returncode, r.stdout + r.stderr


# The quick planner commands of the ```sh blocks, in page order (the plan the text blocks talk about comes first).
quick = re.compile(r"^visco (vcrays|plan|backproject|critical) |^visco sim \S+ --write-world ")
commands = 0
for lang, body in blocks:
    if lang != "sh":
        continue
    for line in body.splitlines():
        command = line.split("  #")[0].strip()
        if not quick.match(command):
            continue
        commands += 1
        status, out = run(command)
        print("$ %s  -> exit %d" % (command, status))
        if status != 0:
            fail("`%s` exited %d: %s" % (command, status, out[-500:]))

# ```text blocks of `$ COMMAND` lines and what each prints.
shown = 0
for lang, body in blocks:
    lines = body.rstrip("\n").splitlines()
    if lang != "text" or not lines or not lines[0].startswith("$ "):
        continue
    k = 0
    while k < len(lines):
        command = lines[k][2:]
        expected = []
        k += 1
        while k < len(lines) and not lines[k].startswith("$ "):
            expected.append(lines[k])
            k += 1
        shown += 1
        status, out = run(command)
        print("$ %s  -> exit %d" % (command, status))
        got = out.splitlines()
        at = 0
        for want in expected:
            prefix = want.endswith("...")
            stem = want[:-3].rstrip() if prefix else want
            while at < len(got) and not (got[at].startswith(stem) if prefix else got[at] == stem):
                at += 1
            if at == len(got):
                fail("`%s` does not print, as the page says:\n  %s\nit prints:\n  %s" %
                     (command, want, "\n  ".join(got[-12:])))
                break
            at += 1

# The words about the plans.
def number(text):
    return float(text.replace("\u2212", "-"))


plan = json.load(open(os.path.join(work, "my_plan.json"))) if os.path.exists(os.path.join(work, "my_plan.json")) else None
m = re.search(r"`my_plan.json`\s+has\s+(\w+)\s+steps\.\s+Step\s+0\s+moves\s+at\s+θ\s+=\s+([−\-\d.]+)°.*?\"ref\":\s+"
              r"\"([^\"]+)\".*?step\s+1\s+moves\s+at\s+θ\s+=\s+([−\-\d.]+)°", page, re.S)
if not m or plan is None:
    fail("the page does not describe my_plan.json's steps as expected, or no command wrote it")
else:
    words = {"one": 1, "two": 2, "three": 3}
    steps = plan["steps"]
    if len(steps) != words.get(m.group(1), -1):
        fail("the page says my_plan.json has %s steps; it has %d" % (m.group(1), len(steps)))
    for i, text in ((0, m.group(2)), (1, m.group(4))):
        decimals = len(text.split(".")[1]) if "." in text else 0
        if i < len(steps) and round(steps[i]["theta_deg"], decimals) != number(text):
            fail("the page says step %d moves at θ = %s°; it is %.6f°" % (i, text, steps[i]["theta_deg"]))
    if steps and steps[0]["terminate"]["ref"] != m.group(3):
        fail("the page says step 0 ends at %s; it is %s" % (m.group(3), steps[0]["terminate"]["ref"]))

m = re.search(r"`(visco plan data/scenes/slot\.json --out \S+)`\s+finds\s+one\s+step:\s+θ\s+=\s+([−\-\d.]+)°,\s+"
              r"complying\s+to\s+`?(vc\d+\.cm\d+)", page)
if not m:
    fail("the page does not state the slot's one-step plan as expected")
else:
    status, out = run(m.group(1))
    written = os.path.join(work, m.group(1).split("--out ")[1].split()[0])
    steps = json.load(open(written))["steps"] if os.path.exists(written) else []
    theta = number(m.group(2))
    decimals = len(m.group(2).split(".")[1]) if "." in m.group(2) else 0
    if status != 0 or len(steps) != 1:
        fail("`%s`: exit %d, %d step(s): %s" % (m.group(1), status, len(steps), out[-300:]))
    elif round(steps[0]["theta_deg"], decimals) != theta or steps[0]["active_rays"] != [m.group(3)]:
        fail("the page says the slot's step moves at θ = %s° complying to %s; it is %.6f° along %s" %
             (m.group(2), m.group(3), steps[0]["theta_deg"], steps[0]["active_rays"]))

print("%d planner command(s) of the page run, %d shown output(s) compared" % (commands, shown))
if commands < 5 or shown < 3:
    fail("the page's examples were not found (%d commands, %d outputs)" % (commands, shown))
print("%d passed, %d failed" % (int(not failures), int(bool(failures))))
sys.exit(1 if failures else 0)
