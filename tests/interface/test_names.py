"""The topic-name rules of saw_ros.interface.names against rclpy's validate_topic_name."""
import random

from rclpy.exceptions import InvalidTopicNameException
from rclpy.validate_topic_name import validate_topic_name

from saw_ros.interface.names import topic_name_problem

NAMES = ['', '/', '~', '~/', '~/a', '~a', 'a~', '/a/~', 'a', '/a', 'a/', '/a/', '1a', '/1a',
         'a/1b', 'a//b', '//a', 'a b', 'bad topic', 'a-b', 'a.b', 'a:b', '$a', '\u00e4', '_a',
         'a_1/b_2', '/saw/pose', '{node}', '{node}/a', '/{ns}/x', '{}', '{1a}', '{a b}', '{a',
         'a}', '{a{b}}', '{a}}', '~/{n}', 'a/{x/y}', '{a/b}', '__a', '/_1', '~~', 'a' * 300]


def rclpy_accepts(name):
    try:
        validate_topic_name(name)
    except InvalidTopicNameException:
        return False
    return True


def test_the_table_of_names_is_judged_as_rclpy_judges_it():
    wrong = [(n, topic_name_problem(n)) for n in NAMES
             if (topic_name_problem(n) is None) != rclpy_accepts(n)]
    assert not wrong
    assert topic_name_problem('bad topic') == "' ' at 3: only letters, digits, _, /, ~, { and } " \
                                              'are allowed'


def test_random_names_are_judged_as_rclpy_judges_them():
    rng = random.Random(33)
    alphabet = 'ab1_/~{} .'
    names = [''.join(rng.choice(alphabet) for _ in range(rng.randint(1, 8)))
             for _ in range(3000)]
    wrong = [n for n in names if (topic_name_problem(n) is None) != rclpy_accepts(n)]
    assert not wrong, wrong[:10]
    assert 300 < sum(topic_name_problem(n) is None for n in names) < 2700    # both kinds tried
