#!/usr/bin/env python3
"""Writes the API reference (docs/api.md) from the public header.

    gen_api_doc.py [--header libas/include/as/as.h] [--out docs/api.md]
    gen_api_doc.py --check docs/api.md [--header ...]

The header is the manual (its comments state each declaration's contract),
so the reference is taken from it rather than written beside it: every
function, type, enum and macro of as.h, in the header's order, grouped by
its section comments (a line of dashes, then the section's title), each with
the comment above it as prose and its declaration as the header spells it.

A comment documents the declarations that follow it up to the next comment
or blank line; a comment after a declaration's semicolon, on its last line,
documents that declaration. A public function with neither is reported as
undocumented, except a release function (as_*_release) or an argument
struct's defaults (as_*_args_default), whose contracts the header's
opening comment states for all of them.

--check regenerates into a temporary file and compares it with the given
page: exit 1, with the differences, when the page is stale; exit 1 when a
function is undocumented; 0 otherwise. Without --check, the page is written
and undocumented functions are listed on stderr (exit 1 when there are any,
after writing). Python 3 standard library only.
"""
import argparse
import difflib
import os
import re
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_HEADER = os.path.join(ROOT, "libas", "include", "as", "as.h")
DEFAULT_OUT = os.path.join(ROOT, "docs", "api.md")

# The header's opening comment states the contract of two families once for
# all ("release functions accept NULL"; an argument struct has "a function
# that fills in the defaults"), so a function of these families needs no
# comment of its own; the reference points to the conventions instead.
CONVENTION = re.compile(r"^as_\w+_(?:release|args_default)$")
CONVENTION_NOTE = "`%s` has no comment of its own: the [conventions](#conventions) state its contract."

# Functions allowed to have no comment of their own: none. Any function
# without one fails the check.
KNOWN_UNDOCUMENTED = set()


def mask_comments(text):
    """The text with every comment's characters replaced by spaces (newlines
    kept, so lines and columns stay where they are), and the comments as
    (start line, end line, start column, text) with 0-based lines."""
    out = list(text)
    comments = []
    i, line, col = 0, 0, 0
    n = len(text)
    while i < n:
        c = text[i]
        if c == '"' or c == "'":
            # A string or character literal: skipped whole, so that "/*"
            # inside one is not a comment.
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            col += j + 1 - i
            i = j + 1
            continue
        if text.startswith("/*", i) or text.startswith("//", i):
            end = text.find("*/", i + 2) + 2 if text[i + 1] == "*" else text.find("\n", i)
            if end < 2 or end == -1:
                end = n
            body = text[i:end]
            comments.append((line, line + body.count("\n"), col, body))
            for k in range(i, end):
                if out[k] != "\n":
                    out[k] = " "
            line += body.count("\n")
            col = len(body) - body.rfind("\n") - 1 if "\n" in body else col + len(body)
            i = end
            continue
        if c == "\n":
            line += 1
            col = 0
        else:
            col += 1
        i += 1
    return "".join(out), comments


def comment_prose(body):
    """A comment's text without its delimiters and leading stars, as lines."""
    if body.startswith("//"):
        return [body[2:].strip()]
    lines = body[2:-2].split("\n")
    result = []
    for k, l in enumerate(lines):
        s = l.rstrip()
        if k > 0:
            s = re.sub(r"^\s*\*(?!/)", "", s) if re.match(r"^\s*\*", s) else s
        result.append(s)
    # Common indentation out, surrounding empty lines out.
    while result and not result[0].strip():
        result.pop(0)
    while result and not result[-1].strip():
        result.pop()
    if not result:
        return []
    first = result[0].strip()
    rest = result[1:]
    indents = [len(l) - len(l.lstrip()) for l in rest if l.strip()]
    cut = min(indents) if indents else 0
    return [first] + [l[cut:] if l.strip() else "" for l in rest]


class Decl:
    def __init__(self, kind, names, lines, doc):
        self.kind = kind        # "function", "struct", "enum", "type", "macro"
        self.names = names      # what it declares, first the main name
        self.lines = lines      # as the header spells them
        self.doc = doc          # the comment after its semicolon, as prose lines


class Group:
    def __init__(self, doc):
        self.doc = doc          # the comment above, as prose lines; [] when none
        self.decls = []


class Section:
    def __init__(self, title):
        self.title = title
        self.groups = []


def classify(code):
    """The kind and names of one declaration, from its comment-free text."""
    flat = " ".join(code.split())
    m = re.match(r"#\s*define\s+(\w+)", flat)
    if m:
        return "macro", [m.group(1)]
    m = re.match(r"typedef\s+(struct|enum|union)\s+\w*\s*\{.*\}\s*(\w+)\s*;$", flat)
    if m:
        return ("enum" if m.group(1) == "enum" else "struct"), [m.group(2)]
    m = re.match(r"typedef\s+(?:struct|enum|union)\s+\w+\s+(\w+)\s*;$", flat)
    if m:
        return "type", [m.group(1)]
    m = re.match(r"typedef\s+[^(]*\(\s*\*\s*(\w+)\s*\)", flat)
    if m:
        return "type", [m.group(1)]
    m = re.match(r"typedef\s+.*?(\w+)\s*;$", flat)
    if m:
        return "type", [m.group(1)]
    m = re.match(r"[^(]*?(\w+)\s*\(", flat)
    if m:
        return "function", [m.group(1)]
    m = re.match(r".*?(\w+)\s*(?:\[[^\]]*\])?\s*;$", flat)
    if m:
        return "variable", [m.group(1)]
    return "other", []


def parse(text):
    """The header as a list of sections; the first, untitled, holds the
    comment that opens the file."""
    masked, comments = mask_comments(text)
    lines = text.split("\n")
    mlines = masked.split("\n")
    starts = {}
    for c in comments:
        starts.setdefault(c[0], []).append(c)

    intro = []
    sections = [Section(None)]
    group = None
    i = 0
    while i < len(lines):
        code = mlines[i].strip()
        if not lines[i].strip():
            group = None                      # a blank line ends a paragraph
            i += 1
            continue
        if not code:
            # A line of comments only: a section rule, a section title or
            # the comment of the declarations below.
            c = starts[i][0]
            prose = comment_prose(c[3])
            end = c[1]
            if prose and re.fullmatch(r"-{8,}", prose[0].strip()) and len(prose) == 1:
                nxt = starts.get(end + 1)
                if nxt:
                    title = " ".join(l.strip() for l in comment_prose(nxt[0][3])).strip()
                    sections.append(Section(title))
                    group = None
                    i = nxt[0][1] + 1
                    continue
            if not intro and len(sections) == 1 and not sections[0].groups and i < 3:
                intro = prose                 # the file's opening comment
                group = None
            else:
                group = Group(prose)
                sections[-1].groups.append(group)
            i = end + 1
            continue
        if code.startswith("#"):
            if re.match(r"#\s*define\s+AS_", code) and not re.match(r"#\s*define\s+AS_\w*_H\b", code):
                j = i
                while mlines[j].rstrip().endswith("\\"):
                    j += 1
                decl_lines, doc, j = finish(lines, starts, i, j)
                add(sections, group, decl_lines, masked_range(mlines, i, j), doc)
                if group is None:
                    group = sections[-1].groups[-1]
                i = j + 1
            else:
                i += 1
            continue
        if code.startswith("extern \"C\"") or code == "}":
            i += 1
            continue
        # A declaration: up to the semicolon outside braces and parentheses.
        depth = 0
        j = i
        while True:
            for ch in mlines[j]:
                if ch in "{(":
                    depth += 1
                elif ch in "})":
                    depth -= 1
            if depth == 0 and mlines[j].rstrip().endswith(";"):
                break
            j += 1
            if j >= len(lines):
                raise ValueError("line %d: a declaration with no end" % (i + 1))
        decl_lines, doc, j = finish(lines, starts, i, j)
        add(sections, group, decl_lines, masked_range(mlines, i, j), doc)
        if group is None:
            group = sections[-1].groups[-1]
        i = j + 1
    return intro, sections


def masked_range(mlines, i, j):
    return "\n".join(mlines[i:j + 1])


def finish(lines, starts, i, j):
    """The declaration's lines (through any comment that starts after its
    end on its last line) and that comment as its own documentation."""
    doc = []
    end = j
    for c in starts.get(j, []):
        before = lines[j][:c[2]].rstrip()
        if before.strip() and before.endswith(";"):
            doc = comment_prose(c[3])
            end = max(end, c[1])
    return lines[i:end + 1], doc, end


def add(sections, group, decl_lines, code, doc):
    kind, names = classify(code)
    if group is None:
        group = Group([])
        sections[-1].groups.append(group)
    group.decls.append(Decl(kind, names, decl_lines, doc))


def slug(heading, used):
    """GitHub's anchor for a heading: lower case, punctuation out, spaces to
    hyphens, a number appended to repeats."""
    s = re.sub(r"[^\w\- ]", "", heading.lower()).replace(" ", "-")
    base, k = s, 1
    while s in used:
        s = "%s-%d" % (base, k)
        k += 1
    used.add(s)
    return s


def prose_md(lines):
    """Comment lines as Markdown: list items kept, the rest joined into
    paragraphs; `*` escaped so that pointers do not turn into emphasis."""
    out = []
    for l in lines:
        s = l.replace("\\", "\\\\").replace("*", "\\*")
        # The API's own names as code, unless the comment quotes them already.
        s = re.sub(r"(?<![`\w])((?:as|AS)_\w+(?:\(\))?)(?![`\w])", r"`\1`", s)
        item = re.match(r"^\s*-\s+(.*)$", s)
        if item:
            out.append("- " + item.group(1))
        elif not s.strip():
            out.append("")
        elif out and out[-1].startswith("- ") and l.startswith(" "):
            out[-1] += " " + s.strip()          # a list item's continuation
        elif out and out[-1] and not out[-1].startswith("- "):
            out[-1] += " " + s.strip()
        else:
            if out and out[-1].startswith("- "):
                out.append("")
            out.append(s.strip())
    return out


def render(intro, sections, header_rel):
    used = set()
    body = []
    index = []
    for sec in sections:
        if not sec.groups:
            continue
        title = sec.title or "Declarations"
        anchor = slug(title, used)
        body += ["", "## %s" % title]
        entries = []
        for g in sec.groups:
            names = [n for d in g.decls for n in d.names]
            heading = ", ".join("`%s`" % n for n in names)
            a = slug(heading, used)
            entries += ["[`%s`](#%s)" % (n, a) for n in names]
            body += ["", "### %s" % heading, ""]
            if g.doc:
                body += prose_md(g.doc) + [""]
            else:
                body += ["%s\n" % (CONVENTION_NOTE % d.names[0]) for d in g.decls
                         if d.kind == "function" and not d.doc and CONVENTION.match(d.names[0])]
            body.append("```c")
            for d in g.decls:
                body += [l.rstrip() for l in d.lines]
            body.append("```")
        index.append("- [%s](#%s): %s" % (title, anchor, ", ".join(entries)))
    head = [
        "# libas API reference",
        "",
        "Generated from [`%s`](../%s) by `scripts/gen_api_doc.py`; do not edit by" % (header_rel, header_rel),
        "hand: change the header's comments and run `python3 scripts/gen_api_doc.py`.",
        "The test `docs_api_reference_is_current` fails when this page differs from",
        "what the header gives, or when a function of the header has no comment.",
        "Every declaration is shown as the header spells it, under the comment",
        "that documents it, in the header's order and sections.",
        "",
    ]
    if intro:
        head += ["## Conventions", ""] + prose_md(intro) + [""]
    head += ["## Index", ""] + index
    return "\n".join(head + body) + "\n"


def undocumented(sections):
    missing = []
    for sec in sections:
        for g in sec.groups:
            for d in g.decls:
                if d.kind == "function" and not g.doc and not d.doc and not CONVENTION.match(d.names[0]):
                    missing.append((sec.title, d.names[0]))
    return missing


def generate(header):
    text = open(header, encoding="utf-8").read()
    intro, sections = parse(text)
    rel = os.path.relpath(os.path.abspath(header), ROOT).replace(os.sep, "/")
    return render(intro, sections, rel), undocumented(sections)


def main():
    p = argparse.ArgumentParser(description="Writes the API reference from the public header.")
    p.add_argument("--header", default=DEFAULT_HEADER)
    p.add_argument("--out", default=DEFAULT_OUT, help="the page to write (default docs/api.md)")
    p.add_argument("--check", metavar="PAGE", help="compare PAGE with a fresh generation instead of writing")
    a = p.parse_args()
    page, missing = generate(a.header)
    new_missing = [(sec, name) for sec, name in missing if name not in KNOWN_UNDOCUMENTED]
    for sec, name in new_missing:
        sys.stderr.write("undocumented: %s (section %s) has no comment above or beside its declaration\n"
                         % (name, sec))
    for name in sorted(KNOWN_UNDOCUMENTED - {name for _, name in missing}):
        sys.stderr.write("note: %s has a comment now (or is gone): take it out of KNOWN_UNDOCUMENTED "
                         "in scripts/gen_api_doc.py\n" % name)
    missing = new_missing
    if a.check:
        # Regenerated into a temporary file, compared with the page as it is.
        with tempfile.NamedTemporaryFile("w", suffix=".md", delete=False, encoding="utf-8") as f:
            f.write(page)
            fresh = f.name
        try:
            new = open(fresh, encoding="utf-8").read().splitlines()
            old = open(a.check, encoding="utf-8").read().splitlines() if os.path.exists(a.check) else []
        finally:
            os.unlink(fresh)
        stale = old != new
        if stale:
            sys.stdout.write("%s is not what %s gives; run python3 scripts/gen_api_doc.py:\n" %
                             (a.check, a.header))
            for l in list(difflib.unified_diff(old, new, a.check, "generated", lineterm="", n=1))[:80]:
                sys.stdout.write("    %s\n" % l)
        if missing:
            sys.stdout.write("%d public function(s) without a comment at the declaration\n" % len(missing))
        if stale or missing:
            return 1
        print("ok - %s matches %s; every function is documented%s" % (
            a.check, a.header, " except %d listed in KNOWN_UNDOCUMENTED" % len(KNOWN_UNDOCUMENTED)
            if KNOWN_UNDOCUMENTED else ""))
        return 0
    with open(a.out + ".tmp", "w", encoding="utf-8") as f:
        f.write(page)
    os.replace(a.out + ".tmp", a.out)
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
