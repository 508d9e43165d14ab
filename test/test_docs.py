"""The documents agree with the code they describe, link to what exists, and do not narrate."""
from __future__ import annotations

import re

import pytest
import yaml
from conftest import REPO

from drill_twin.ros.parameters import PARAMETERS, markdown_table

README_MAX_LINES = 250
LINK = re.compile(r'!?\[(?:[^\]\\]|\\.)*\]\(\s*<?([^)\s>]+)>?(?:\s+"[^"]*")?\s*\)')
"""An inline Markdown link or image; group 1 is its target."""
FENCE = re.compile(r'^(```|~~~).*?^\1', re.MULTILINE | re.DOTALL)
JOURNAL = {
    'a work session': re.compile(r'\bsessions?\b', re.IGNORECASE),
    'a numbered work period': re.compile(r'\bwork periods?\b', re.IGNORECASE),
    'what was tried or found': re.compile(r'\bwe (tried|found|noticed)\b', re.IGNORECASE),
    'an issue number': re.compile(r'\bissue \d+', re.IGNORECASE),
    'a dated entry': re.compile(r'^\s*(\*\*|[-*] )?\d{4}-\d{2}-\d{2}\b'),
    'a change since a date': re.compile(
        r'\b(since|until|before|after) (the )?\d{4}-\d{2}-\d{2}\b', re.IGNORECASE),
}
"""What a line of a document that narrates the development looks like."""


def _documents():
    return [REPO / 'README.md', *sorted((REPO / 'docs').glob('*.md'))]


def _name(path):
    return str(path.relative_to(REPO))


def _slug(heading: str) -> str:
    """Return the anchor GitHub gives a heading: its text lower-cased, punctuation dropped."""
    text = re.sub(r'\[([^\]]*)\]\([^)]*\)', r'\1', heading).strip().lower()
    kept = ''.join(c for c in text if c.isalnum() or c in ' -_')
    return kept.replace(' ', '-')


def _anchors(path) -> set[str]:
    seen: dict[str, int] = {}
    anchors = set()
    for line in FENCE.sub('', path.read_text()).splitlines():
        match = re.match(r'#{1,6}\s+(.*?)\s*#*\s*$', line)
        if match:
            slug = _slug(match.group(1))
            count = seen.get(slug, 0)
            seen[slug] = count + 1
            anchors.add(slug if count == 0 else f'{slug}-{count}')
    return anchors


def _links(path):
    """Yield the relative link targets of a document, outside its code blocks."""
    for target in LINK.findall(FENCE.sub('', path.read_text())):
        if not re.match(r'[a-z][a-z0-9+.-]*:', target, re.IGNORECASE):
            yield target


def test_the_link_pattern_finds_links_and_images_but_not_code(tmp_path):
    path = tmp_path / 'probe.md'
    path.write_text('See [a](docs/A.md#x) and ![b](figures/b.png "t"), [web](https://x.org).\n'
                    '```\n[not](a/link.md)\n```\n')
    assert list(_links(path)) == ['docs/A.md#x', 'figures/b.png']


def test_a_heading_gets_githubs_anchor():
    assert _slug('Lift-off at δ = 0.1') == 'lift-off-at-δ--01'
    assert _slug('The model in time (Sect. 2.2–2.9, 4)') == 'the-model-in-time-sect-2229-4'
    assert _slug('Viewing a log: `drill-twin view`') == 'viewing-a-log-drill-twin-view'


@pytest.mark.parametrize('document', _documents(), ids=_name)
def test_every_relative_link_resolves_to_a_file_of_the_repository(document):
    broken = []
    for target in _links(document):
        path_part, _, anchor = target.partition('#')
        resolved = (document.parent / path_part).resolve() if path_part else document
        if not resolved.exists() or REPO.resolve() not in (resolved, *resolved.parents):
            broken.append(target)
        elif anchor and resolved.suffix == '.md' and anchor not in _anchors(resolved):
            broken.append(f'{target} (no such heading)')
    assert not broken, broken


def test_the_readme_is_short():
    lines = len((REPO / 'README.md').read_text().splitlines())
    assert lines <= README_MAX_LINES, lines


@pytest.mark.parametrize('document', _documents(), ids=_name)
def test_no_document_narrates_the_development(document):
    found = [f'{_name(document)}:{number}: {what}: {line.strip()[:80]}'
             for number, line in enumerate(document.read_text().splitlines(), 1)
             for what, pattern in JOURNAL.items() if pattern.search(line)]
    assert not found, '\n'.join(found)


@pytest.mark.parametrize('line', [
    'Measured in the twenty-third session:', 'Work period 4: the envelope',
    'We tried a smaller step.', 'the sweep of issue 10', '2026-12-02: the map again',
    '**2026-12-03, evening.** Faster.', 'the default since 2026-12-03'])
def test_the_journal_patterns_catch_a_journal_line(line):
    assert any(pattern.search(line) for pattern in JOURNAL.values())


@pytest.mark.parametrize('line', [
    'measured 2026-12-04 in an environment without tf2_msgs', '| 2026-12-04 runs | 41.7 |',
    'the issue\'s scenario', 'we take the invariant reading'])
def test_a_measurement_date_is_not_a_journal_entry(line):
    assert not [what for what, pattern in JOURNAL.items() if pattern.search(line)]


def test_parameter_table_matches_the_declared_parameters():
    text = (REPO / 'docs' / 'ROS-INTERFACE.md').read_text()
    assert markdown_table() in text, 'regenerate the table with parameters.markdown_table()'


def test_shipped_twin_parameters_are_declared_with_the_same_defaults():
    shipped = yaml.safe_load((REPO / 'config' / 'twin.yaml').read_text())
    values = shipped['drill_twin']['ros__parameters']
    declared = {p.name: p.default for p in PARAMETERS}
    assert set(values) <= set(declared), set(values) - set(declared)
    for name, value in values.items():
        assert value == declared[name], (name, value, declared[name])
