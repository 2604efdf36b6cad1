#!/usr/bin/env python3
"""Runs the commands a Markdown page shows and compares their output with the
output the page shows.

    run_doc_commands.py [--build BUILD_DIR] PAGE.md TOOL_DIR SOURCE_DIR [SCENES_DIR]

What the page shows, and what runs:

- A fenced block marked ```console holds commands, each on a line that
  starts with "$ ", followed by the output it prints (standard output and
  standard error together), up to the next "$ " line or the block's end.
  A command with no lines after it must print nothing.
- A fenced block of any other kind whose first line is a comment naming a
  file ("# make_rays.py", "# scene.obj") is that file: it is written, at
  that point of the page, into the directory the commands run in.
- Every other block (```sh, ```python without such a line, plain ```) is
  shown, not run.

The commands of a page run in order in one bash shell, so that `cd`,
variables and `echo $?` carry over from one to the next. The shell starts in
a scratch directory that stands for the repository root: it holds `scenes`
(a link to the bundled scenes), and `../shared` beside it is a link to the
folder holding the shared scenes, when there is one. With --build, it holds
`build` too, a link to the build tree BUILD_DIR, and `examples` and `tests`,
links to the source's, so that a page can install that tree and build the
programs of the source against the install (docs/embedding.md). HOME is an
empty scratch directory. The tools' directory comes first on PATH; LC_ALL=C
and TZ=UTC.

A command must exit 0, unless the next command is `echo $?`, which shows
its status.

Comparison, line by line, with trailing blanks and trailing empty lines
ignored. In the expected text, `…` stands for any text within its line, and
a line that is `…` alone for any number of lines, none included. Figures that
differ from run to run are masked on both sides before they are compared:

- a number before ms, s, Mrays/s, MB/s or GB/s ("303.3 ms", "8.56 Mrays/s");
- the number after "Mrays/s:";
- a count of threads or cores ("2 threads", "1 thread", "(2 cores)");
- in JSON, the value of a key ending in _ms or _per_s, and of "threads" and
  "cores";
- dates and times of day ("2026-11-22", "Nov 22", "07:02", "07:02:33");
- the six random characters of a temporary file's name (NAME.tmp.XXXXXX);
- the scratch directory's absolute path, which reads as $PWD, and the
  scratch HOME's, which reads as $HOME.

Prints one line per command, "ok - ..." or "FAIL - ..." with the
differences; exits 0 when every command matched, 1 when one did not, 77
(skipped) when the page uses ../shared and the shared scenes are absent,
except under CI=true, where that is a failure.
"""
import difflib
import os
import re
import shutil
import subprocess
import sys
import tempfile

FILE_BLOCK_NAME = re.compile(r"^(?:#|//)\s*([\w.-]+\.[A-Za-z0-9]+)\s*$")
MARKER = "\x1e"
WILDCARD = "\u2026"
MONTHS = "Jan|Feb|Mar|Apr|May|Jun|Jul|Aug|Sep|Oct|Nov|Dec"
MASKS = [
    (re.compile(r"\b\d+(?:\.\d+)?(?:[eE][-+]?\d+)?( ?)(Mrays/s|GB/s|MB/s|ms|s)\b"), r"#\1\2"),
    (re.compile(r"(Mrays/s:\s+)\d+(?:\.\d+)?"), r"\1#"),
    (re.compile(r"\b\d+ (threads?|cores?)\b"), r"# \1"),
    (re.compile(r'("(?:\w+_ms|\w+_per_s|threads|cores)": )(?:-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?|null)'), r"\1#"),
    (re.compile(r"\b\d{4}-\d{2}-\d{2}\b"), "#date"),
    (re.compile(r"\b(?:%s) +\d{1,2}\b" % MONTHS), "#date"),
    (re.compile(r"\b\d{2}:\d{2}(?::\d{2}(?:\.\d+)?)?\b"), "#time"),
    (re.compile(r"(\.tmp\.)[A-Za-z0-9]{6}\b"), r"\1XXXXXX"),
]


def parse_page(text):
    """The page as a list of steps: ("file", name, content) and
    ("command", command, expected lines, line number)."""
    steps = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        m = re.match(r"^(\s*)(```+|~~~+)\s*([\w+-]*)", lines[i])
        if not m:
            i += 1
            continue
        indent, fence, kind = m.group(1), m.group(2), m.group(3)
        start = i + 1
        i = start
        while i < len(lines) and not lines[i].strip().startswith(fence):
            i += 1
        body = [l[len(indent):] if l.startswith(indent) else l.lstrip() for l in lines[start:i]]
        i += 1
        if kind == "console":
            current = None
            for n, line in enumerate(body):
                if line.startswith("$ "):
                    current = ("command", line[2:], [], start + n + 1)
                    steps.append(current)
                elif current is not None:
                    current[2].append(line)
                elif line.strip():
                    raise ValueError("line %d: output before the first command of a console block" % (start + n + 1))
        elif body and FILE_BLOCK_NAME.match(body[0]):
            steps.append(("file", FILE_BLOCK_NAME.match(body[0]).group(1), "\n".join(body) + "\n"))
    return steps


def mask(line, scratch, home):
    line = line.replace(scratch, "$PWD").replace(home, "$HOME")
    for pattern, repl in MASKS:
        line = pattern.sub(repl, line)
    return line.rstrip()


def trim(lines):
    lines = list(lines)
    while lines and not lines[-1].strip():
        lines.pop()
    return lines


def matches(expected, actual):
    """Whether the actual lines match the expected ones, with `…` wildcards."""
    patterns = [None if e.strip() == WILDCARD else
                re.compile(".*".join(re.escape(p) for p in e.split(WILDCARD)) + r"\Z") for e in expected]
    memo = {}

    def match(i, j):
        if (i, j) in memo:
            return memo[(i, j)]
        if i == len(patterns):
            result = j == len(actual)
        elif patterns[i] is None:
            result = match(i + 1, j) or (j < len(actual) and match(i, j + 1))
        else:
            result = j < len(actual) and patterns[i].match(actual[j]) is not None and match(i + 1, j + 1)
        memo[(i, j)] = result
        return result

    sys.setrecursionlimit(max(10000, 4 * (len(expected) + len(actual))))
    return match(0, 0)


def shell_quote(s):
    return "'" + s.replace("'", "'\\''") + "'"


def main():
    args = sys.argv[1:]
    build = None
    if len(args) >= 2 and args[0] == "--build":
        build, args = os.path.abspath(args[1]), args[2:]
    if len(args) not in (3, 4):
        sys.stderr.write("usage: run_doc_commands.py [--build BUILD_DIR] PAGE.md TOOL_DIR SOURCE_DIR [SCENES_DIR]\n")
        return 2
    page, tool_dir, src = (os.path.abspath(a) for a in args[:3])
    scenes = os.path.abspath(args[3]) if len(args) == 4 else None
    name = os.path.relpath(page, src)
    steps = parse_page(open(page, encoding="utf-8").read())
    commands = [s for s in steps if s[0] == "command"]
    if not commands:
        print("FAIL - %s shows no command in a console block" % name)
        return 1
    if any("../shared/" in s[1] for s in commands) and not (scenes and os.path.isdir(scenes)):
        if os.environ.get("CI") == "true":
            print("FAIL - %s needs the shared scenes, '%s' is absent and CI=true" % (name, scenes))
            return 1
        print("skipped: %s needs the shared scenes and '%s' is absent (../shared/scenes)" % (name, scenes))
        return 77

    base = tempfile.mkdtemp(prefix="as-doc.")
    try:
        root = os.path.join(base, "libas")
        os.mkdir(root)
        os.symlink(os.path.join(src, "scenes"), os.path.join(root, "scenes"))
        if build:
            os.symlink(build, os.path.join(root, "build"))
            for d in ("examples", "tests"):
                os.symlink(os.path.join(src, d), os.path.join(root, d))
        home = os.path.join(base, "home")
        os.mkdir(home)
        if scenes and os.path.isdir(scenes):
            os.symlink(os.path.dirname(scenes), os.path.join(base, "shared"))
        script = ["exec 2>&1", "cd %s || exit 99" % shell_quote(root), "__doc_rc=0"]
        for k, step in enumerate(steps):
            if step[0] == "file":
                script.append("cat > %s <<'__AS_DOC_FILE__'\n%s__AS_DOC_FILE__" % (shell_quote(step[1]), step[2]))
            else:
                # The previous command's status, for `echo $?`.
                script.append("(exit $__doc_rc)")
                script.append(step[1])
                script.append("__doc_rc=$?; printf '\\n%s%%d\\n' $__doc_rc" % MARKER)
        env = dict(os.environ, PATH=os.path.abspath(tool_dir) + os.pathsep + os.environ.get("PATH", ""),
                   LC_ALL="C", TZ="UTC", HOME=home)
        env.pop("CDPATH", None)
        script_path = os.path.join(base, "page.sh")
        with open(script_path, "w") as f:
            f.write("\n".join(script) + "\n")
        p = subprocess.run(["bash", "--noprofile", "--norc", script_path], stdin=subprocess.DEVNULL, env=env,
                           capture_output=True, text=True, timeout=float(os.environ.get("AS_DOC_TIMEOUT", 1200)))
        parts = re.split(r"\n%s(\d+)\n" % MARKER, p.stdout)
        outputs = [(parts[2 * i], int(parts[2 * i + 1])) for i in range((len(parts) - 1) // 2)]
        failed = False
        for k, (_, cmd, expected, line) in enumerate(commands):
            what = "%s:%d: $ %s" % (name, line, cmd)
            if k >= len(outputs):
                print("FAIL - %s: did not run (the shell stopped: %s)" % (what, (p.stdout + p.stderr)[-300:]))
                failed = True
                continue
            out, rc = outputs[k]
            shows_status = k + 1 < len(commands) and commands[k + 1][1].strip() == "echo $?"
            exp = trim(mask(l, root, home) for l in expected)
            act = trim(mask(l, root, home) for l in out.splitlines())
            problems = []
            if rc != 0 and not shows_status:
                problems.append("exit status %d (a command must exit 0 unless the next one is `echo $?`)" % rc)
            if not matches(exp, act):
                # Lines that match where they stand are shown as printed, so
                # that the differences are the lines that do not.
                shown = [a if i < len(act) and WILDCARD in e and matches([e], [a]) else e
                         for i, (e, a) in enumerate(zip(exp, act + [""] * len(exp)))]
                diff = difflib.unified_diff(shown, act, "shown in the page", "printed", lineterm="", n=1)
                problems.append("output differs (masked):\n    " + "\n    ".join(list(diff)[:60]))
            if problems:
                failed = True
                print("FAIL - %s: %s" % (what, "; ".join(problems)))
            else:
                print("ok - %s" % what)
        return 1 if failed else 0
    finally:
        shutil.rmtree(base, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
