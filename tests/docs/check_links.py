#!/usr/bin/env python3
"""Checks that every relative link in README.md and docs/*.md resolves.

A link to a file must name an existing file or folder (relative to the linking file); a link
with an #anchor must name a heading of the target Markdown file (GitHub's slugs: lower case,
punctuation dropped, spaces to hyphens, repeats numbered -1, -2, ...). Links to other sites and
mailto: are not checked. Usage: check_links.py SOURCE_DIR. Exit 1 with one line per broken link.
"""
import os
import re
import sys

LINK = re.compile(r'(?<!\!)\[(?:[^\[\]]|\[[^\]]*\])*\]\(([^()\s]+)(?:\s+"[^"]*")?\)|!\[[^\]]*\]\(([^()\s]+)\)')
HEADING = re.compile(r'^(#{1,6})\s+(.*?)\s*#*\s*$')
FENCE = re.compile(r'^\s*(```|~~~)')


def slug(heading):
    text = re.sub(r'<[^>]+>', '', heading).strip().lower()
    text = re.sub(r'\[([^\]]*)\]\([^)]*\)', r'\1', text)  # a link in a heading counts as its text
    text = ''.join(c for c in text if c.isalnum() or c in ' -_')
    return text.replace(' ', '-')


def lines_outside_code(text):
    """The file's lines with those inside fenced or indented code blocks blanked."""
    out, fenced, previous_blank = [], False, True
    for line in text.split('\n'):
        if FENCE.match(line):
            fenced = not fenced
            out.append('')
            continue
        indented = line.startswith('    ') and previous_blank
        if fenced or indented:
            out.append('')
            previous_blank = previous_blank if indented else False
            continue
        previous_blank = line.strip() == ''
        out.append(re.sub(r'`[^`]*`', '``', line) if not HEADING.match(line) else line)
    return out


def anchors(path, cache={}):
    if path not in cache:
        seen, result = {}, set()
        with open(path, encoding='utf-8') as f:
            for line in lines_outside_code(f.read()):
                m = HEADING.match(line)
                if not m:
                    continue
                base = slug(m.group(2))
                n = seen.get(base, 0)
                seen[base] = n + 1
                result.add(base if n == 0 else f'{base}-{n}')
        cache[path] = result
    return cache[path]


def check(source_dir):
    files = [os.path.join(source_dir, 'README.md')]
    docs = os.path.join(source_dir, 'docs')
    if os.path.isdir(docs):
        files += sorted(os.path.join(docs, f) for f in os.listdir(docs) if f.endswith('.md'))
    broken, count = [], 0
    for path in files:
        with open(path, encoding='utf-8') as f:
            lines = lines_outside_code(f.read())
        for number, line in enumerate(lines, 1):
            for m in LINK.finditer(line):
                target = m.group(1) or m.group(2)
                if re.match(r'^[a-z][a-z0-9+.-]*:', target):
                    continue  # https:, mailto:
                count += 1
                file_part, _, anchor = target.partition('#')
                where = f'{os.path.relpath(path, source_dir)}:{number}: {target}'
                resolved = os.path.normpath(os.path.join(os.path.dirname(path), file_part)) if file_part else path
                if not os.path.exists(resolved):
                    broken.append(f'{where}: no file {os.path.relpath(resolved, source_dir)}')
                    continue
                if anchor and resolved.endswith('.md') and anchor not in anchors(resolved):
                    broken.append(f'{where}: no heading with the anchor #{anchor} in '
                                  f'{os.path.relpath(resolved, source_dir)}')
    return broken, count, len(files)


def main():
    if len(sys.argv) != 2:
        print(__doc__.strip().split('\n')[-1], file=sys.stderr)
        return 2
    broken, count, files = check(sys.argv[1])
    for line in broken:
        print(line)
    print(f'{count} relative links in {files} files, {len(broken)} broken')
    return 1 if broken else 0


if __name__ == '__main__':
    sys.exit(main())
