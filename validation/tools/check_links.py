"""Every relative link and image in README.md, CHANGELOG.md, docs/*.md and validation/README.md names a file
that exists, and every docs/NAME.md or docs/NAME.png named in their text exists too.

    python -m validation.tools.check_links        # prints each broken link; exit status 1 if any

Markdown links and images ``[text](target)`` / ``![alt](target)`` are resolved against the page's folder
(web addresses and ``#anchors`` are skipped; a target's own ``#anchor`` is dropped). Paths written as text,
``docs/NAME.md`` and the like, are resolved against the repository root, as the pages write them.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
NAMED = re.compile(r"(?<![\w/.])((?:docs|validation|scenes|tests)/[\w/.-]+\.(?:md|png|gif|py|yaml))")


def pages(root=ROOT):
    found = [root / "README.md", root / "CHANGELOG.md", root / "validation" / "README.md"]
    found += sorted((root / "docs").glob("*.md"))
    return [p for p in found if p.exists()]


def broken(page, root=ROOT):
    """(line number, target) of every link or named path on the page that does not exist."""
    out = []
    in_code = False
    for number, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1):
        if line.lstrip().startswith("```"):
            in_code = not in_code
            continue
        bare = re.sub(r"`[^`]*`", "", line)  # a link inside inline code is code, not a link
        for target in LINK.findall(bare):
            if re.match(r"[a-z]+:", target) or target.startswith("#"):
                continue
            path = (page.parent / target.split("#")[0]).resolve()
            if not path.exists():
                out.append((number, target))
        if in_code:
            continue
        for name in NAMED.findall(line):
            if "*" in name or "{" in name or "NAME" in name or "former docs/" in line or name.rstrip(".").endswith("WxH"):
                continue
            if not (root / name.rstrip(".")).exists():
                out.append((number, name))
    return out


def main(argv=None):
    bad = 0
    for page in pages():
        for number, target in broken(page):
            print(f"{page.relative_to(ROOT)}:{number}: {target} does not exist")
            bad += 1
    print(f"{bad} broken link{'s' if bad != 1 else ''} in {len(pages())} pages")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
