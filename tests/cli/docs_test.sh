#!/usr/bin/env bash
# docs/cli.md is the whole command line: a section for every command of `linebake --help` (and
# every bench kind) naming every long option its --help prints, the exit-code table, and every
# deprecated spelling of tools/cli_contract.cpp with its replacement.
# Usage: docs_test.sh LINEBAKE REPO_ROOT
set -u
bin="$1"
root="$2"
python3 - "$bin" "$root" <<'PY'
import re, subprocess, sys
binary, root = sys.argv[1], sys.argv[2]
doc = open(f"{root}/docs/cli.md").read()

def help_of(args):
    return subprocess.run([binary, *args, "--help"], capture_output=True, text=True).stdout

def options(text):
    names = set()
    for line in text.splitlines():
        if re.match(r"^\s+-", line):
            names.update(n for n in re.findall(r"--[a-z0-9][a-z0-9-]*", line.split("  ")[1]
                                               if line.startswith("  ") else line)
                         if n not in ("--help",))
    return names

def subcommands(text):
    part = text.split("Subcommands:", 1)
    return re.findall(r"^\s{2}(\S+)", part[1], re.M) if len(part) > 1 else []

# Sections: "## `name`" headings (several names may share one heading), up to the next "## ".
sections = {}
for m in re.finditer(r"^## (.+)$", doc, re.M):
    end = doc.find("\n## ", m.end())
    body = doc[m.end(): end if end >= 0 else len(doc)]
    for name in re.findall(r"`([^`]+)`", m.group(1)):
        sections[name] = body

problems = []
commands = [[c] for c in subcommands(help_of([]))]
for c in list(commands):
    commands += [c + [k] for k in subcommands(help_of(c))]
checked = 0
for c in commands:
    name = " ".join(c)
    text = help_of(c)
    if subcommands(text):  # bench: its kinds have the options
        continue
    if name not in sections:
        problems.append(f"no section '## `{name}`' in docs/cli.md")
        continue
    for option in sorted(options(text)):
        checked += 1
        if not re.search(re.escape(option) + r"(?![a-z0-9-])", sections[name]):
            problems.append(f"{name}: {option} is not in its section of docs/cli.md")
# The exit-code table.
for code in ("0", "1", "2", "3", "4"):
    if not re.search(rf"^\| {code} \|", doc, re.M):
        problems.append(f"exit code {code} is not in the table")
# Deprecated spellings, from the table in tools/cli_contract.cpp.
source = open(f"{root}/tools/cli_contract.cpp").read()
for command, old, new in re.findall(r'\{"(\w+)", "(--[a-z-]+)", "([^"]*)"\}', source):
    rows = [l for l in doc.splitlines() if l.startswith("|") and old in l and command in l]
    if not rows or (new and not any(new in r for r in rows)):
        problems.append(f"deprecated {command} {old} -> {new or 'positional'} is not documented")
for p in problems:
    print("FAIL:", p)
print(f"docs/cli.md: {len(commands)} commands, {checked} options checked, {len(problems)} problems")
sys.exit(1 if problems or checked < 100 else 0)
PY
