#!/usr/bin/env python3
"""Checks that the documentation's commands are the programs' commands.

Every command in the README's "Commands" table is a subcommand of `revolve --help` (or is
revolved), and every subcommand of `revolve --help` is in that table. Every usage line of
docs/commands.md (an indented line starting with `revolve` or `revolved`) names a command and
verbs that exist, and every --option it shows is in that command's --help.
Usage: check_commands.py SOURCE_DIR REVOLVE REVOLVED. Exit 1 with one line per mismatch.
"""
import os
import re
import subprocess
import sys


def help_text(program, args, cache={}):
    key = (program, *args)
    if key not in cache:
        cache[key] = run_help(program, args)
    return cache[key]


def run_help(program, args):
    run = subprocess.run([program, *args, '--help'], capture_output=True, text=True, timeout=60)
    if run.returncode != 0:
        return None
    return run.stdout


def subcommands(text):
    """The names listed under SUBCOMMANDS: in a CLI11 help text."""
    names, inside = [], False
    for line in text.split('\n'):
        if re.match(r'^\s*subcommands:?\s*$', line, re.IGNORECASE):
            inside = True
            continue
        if inside:
            m = re.match(r'^  (\S+)', line)
            if m:
                names.append(m.group(1))
            elif line.strip() and not line.startswith(' '):
                inside = False
    return names


def readme_commands(readme):
    """The README's Commands table: the (program, command) pairs its first column names in full
    (`revolve scan ...`), and every word it names (`revolve start` / `abort` names both)."""
    text = open(readme, encoding='utf-8').read()
    section = text.split('\n## Commands\n', 1)[1].split('\n## ', 1)[0]
    full, words = [], set()
    for line in section.split('\n'):
        if not line.startswith('| `revolve'):
            continue
        for code in re.findall(r'`([^`]+)`', line.split('|')[1]):
            parts = code.split()
            if parts[0] in ('revolve', 'revolved'):
                full.append((parts[0], parts[1] if len(parts) > 1 and parts[0] == 'revolve' else None))
                parts = parts[1:]
            if parts:
                words.add(parts[0])
    return full, words


def main():
    if len(sys.argv) != 4:
        print(__doc__.strip().split('\n')[-1], file=sys.stderr)
        return 2
    source, revolve, revolved = sys.argv[1:]
    programs = {'revolve': revolve, 'revolved': revolved}
    problems = []
    top = help_text(revolve, [])
    if top is None:
        print('revolve --help failed')
        return 1
    known = subcommands(top)
    if not known:
        print('no SUBCOMMANDS in revolve --help:\n' + top)
        return 1
    table, listed = readme_commands(os.path.join(source, 'README.md'))
    for program, command in table:
        if program == 'revolve' and command not in known:
            problems.append(f'README.md: `revolve {command}` is not a command of revolve --help')
    for command in known:
        if command not in listed and command != 'help':
            problems.append(f'README.md: the Commands table lacks `revolve {command}`')
    # The usage lines of docs/commands.md.
    usage_count = 0
    with open(os.path.join(source, 'docs', 'commands.md'), encoding='utf-8') as f:
        for number, line in enumerate(f, 1):
            m = re.match(r'^    (revolved?)\b(.*)$', line.rstrip('\n'))
            if not m:
                continue
            usage_count += 1
            program, rest = m.group(1), m.group(2).split('#', 1)[0]
            words = rest.split()
            path = []
            text = help_text(programs[program], [])
            # The command and verbs: leading bare words that are subcommands.
            for word in [w for w in words if re.match(r'^[a-z][a-z-]*$', w)]:
                if word in subcommands(text):
                    path.append(word)
                    text += help_text(programs[program], path) or ''
            if program == 'revolve' and not path:
                problems.append(f'docs/commands.md:{number}: no revolve command in "{line.strip()}"')
                continue
            for option in re.findall(r'(?<![\w-])(--[a-z][a-z0-9-]*|-[a-zA-Z])\b', rest):
                if not re.search(r'(?<![\w-])' + re.escape(option) + r'\b', text):
                    problems.append(f'docs/commands.md:{number}: {program} {" ".join(path)}: '
                                    f'{option} is not in its --help')
    for problem in problems:
        print(problem)
    print(f'{len(table)} README commands, {usage_count} usage lines, {len(problems)} problems')
    return 1 if problems else 0


if __name__ == '__main__':
    sys.exit(main())
