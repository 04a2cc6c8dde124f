"""
The topic table (saw_ros/interface/topics.py) is the one source.

The generated msg_config/record_topics.yaml and the README's topic table agree with it.
"""
from pathlib import Path
import re

from saw_ros.interface import topics
import yaml

ROOT = Path(__file__).resolve().parents[2]


def test_record_topics_yaml_is_generated_from_the_table():
    """
    Check msg_config/record_topics.yaml against the table.

    Regenerate with `python -m saw_ros.interface.topics --write-record-yaml
    msg_config/record_topics.yaml`.
    """
    text = (ROOT / 'msg_config' / 'record_topics.yaml').read_text(encoding='utf-8')
    assert text == topics.record_topics_yaml()
    doc = yaml.safe_load(text)
    assert doc['topics'] == topics.recorded_topics()
    assert doc['exclude'] == [topics.IMAGE, topics.READY]


def _readme_topics():
    text = (ROOT / 'README.md').read_text(encoding='utf-8')
    section = text.split('### Topics', 1)[1].split('\n#', 1)[0]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip('|').split('|')]
        if len(cells) < 7 or not cells[0].startswith('`/'):
            continue
        for name in re.findall(r'`(/[^`]+)`', cells[0]):
            rows[name] = (cells[1], cells[-2], cells[-1])
    return rows


def test_readme_topic_table_matches_the_table():
    rows = _readme_topics()
    assert set(rows) == set(topics.BY_NAME), set(rows) ^ set(topics.BY_NAME)
    for name, (type_cell, readers, publisher) in rows.items():
        t = topics.topic(name)
        assert type_cell.startswith(t.type.replace('/msg/', '/')), (name, type_cell, t.type)
        assert publisher == t.publisher, (name, publisher, t.publisher)
        assert readers == (', '.join(topics.subscribers(t)) or '-'), (name, readers)


def test_every_subscribed_topic_says_what_a_spoofed_message_can_do():
    """Every topic a node of ours parses (the recorder parses none) states what it trusts."""
    for t in topics.TOPICS + topics.RCL_TOPICS:
        assert bool(t.subscribers) == bool(t.trust), t.name
    assert {t.name for t in topics.subscribed_by('recorder')} == set(topics.recorded_topics())


def test_security_doc_states_what_each_subscribed_topic_trusts():
    """docs/security.md's per-topic table is the topic table's readers and trust, row by row."""
    text = (ROOT / 'docs' / 'security.md').read_text(encoding='utf-8')
    for t in topics.TOPICS + topics.RCL_TOPICS:
        if t.trust:
            row = f"| `{t.name}` | {t.type.replace('/msg/', '/')} | {t.subscribers} | {t.trust} |"
            assert row in text, row
