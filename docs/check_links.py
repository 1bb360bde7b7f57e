#!/usr/bin/env python3
"""Check that every relative link and image in README.md and docs/**/*.md resolves.

Usage: python3 docs/check_links.py   (from anywhere; paths are taken from this file's place)

Checks inline links and images `[text](target)` / `![alt](target)`, reference definitions
`[name]: target`, and HTML `<img src="...">` / `<a href="...">`. Targets with a scheme
(http:, https:, mailto:) are skipped; text inside fenced code blocks and inline code is ignored.
A target `file#anchor` must name an existing file, and the anchor must match a heading of that
file (mdBook/GitHub style: lower case, punctuation dropped, spaces to hyphens). A bare `#anchor`
is checked against the page itself. Exit status 0 when everything resolves, 1 otherwise.
"""
import re
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent

INLINE = re.compile(r'!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+"[^"]*")?\s*\)')
REFDEF = re.compile(r'^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+"[^"]*")?\s*$', re.M)
HTML = re.compile(r'<(?:img|a)\b[^>]*?\b(?:src|href)\s*=\s*"([^"]+)"', re.I)
SCHEME = re.compile(r'^[a-zA-Z][a-zA-Z0-9+.-]*:')


def strip_code(text):
    out, fence = [], None
    for line in text.split('\n'):
        m = re.match(r'^\s*(```+|~~~+)', line)
        if m:
            if fence is None:
                fence = m.group(1)[:3]
            elif line.strip().startswith(fence):
                fence = None
            out.append('')
            continue
        out.append('' if fence else re.sub(r'`+[^`]*`+', '', line))
    return '\n'.join(out)


def slug(heading):
    h = re.sub(r'`', '', heading.strip().lower())
    h = re.sub(r'[^\w\- ]', '', h)
    return h.replace(' ', '-')


def anchors(path):
    text = strip_code(path.read_text(encoding='utf-8'))
    seen, result = {}, set()
    for m in re.finditer(r'^#{1,6}\s+(.*?)\s*#*\s*$', path.read_text(encoding='utf-8'), re.M):
        s = slug(m.group(1))
        n = seen.get(s, 0)
        seen[s] = n + 1
        result.add(s if n == 0 else f'{s}-{n}')
    result.update(re.findall(r'<a\s+(?:id|name)="([^"]+)"', text))
    return result


def targets(text):
    text = strip_code(text)
    for rx in (INLINE, REFDEF, HTML):
        for m in rx.finditer(text):
            yield m.group(1)


def main():
    files = [ROOT / 'README.md'] + sorted(p for p in DOCS.rglob('*.md'))
    bad, count = [], 0
    for f in files:
        for t in targets(f.read_text(encoding='utf-8')):
            if SCHEME.match(t):
                continue
            count += 1
            path, _, frag = t.partition('#')
            dest = f if path == '' else (f.parent / path).resolve()
            rel = f.relative_to(ROOT)
            if not dest.exists():
                bad.append(f'{rel}: {t}: no such file')
            elif frag and dest.suffix == '.md' and frag not in anchors(dest):
                bad.append(f'{rel}: {t}: no heading #{frag} in {dest.relative_to(ROOT)}')
    for b in bad:
        print(b)
    print(f'{len(files)} files, {count} relative links and images, {len(bad)} broken')
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
