"""
The SROS2 access-control policy of our nodes, generated from the topic table (pure: no rclpy).

The policy is sros2's own format (``<policy version="0.2.0">``, schema
``sros2/policy/schemas/policy.xsd``): one enclave ``/saw_ros/<node>`` a node, whose profile
allows exactly what the node does: publish the topics the table says it publishes, subscribe to
the ones it says it reads, answer its own parameter services (and the simulator its ``~/reset``,
the player its controls), call the simulator's ``get_parameters`` where it follows the simulator
(``saw_ros.ros.simulator_parameters``), and publish ``/rosout`` and ``/parameter_events`` as
every rclpy node does. ``ros2 security create_permission`` turns it into the DDS permissions
each enclave's keystore entry needs; docs/security.md says how, and what it protects.
"""
from __future__ import annotations

from typing import Dict, List, Tuple
import xml.etree.ElementTree as ET

from saw_ros.interface import topics

VERSION = '0.2.0'
ENCLAVE_PREFIX = '/saw_ros'
# Services every rclpy node answers: its parameters (sros2's common/node/parameters.xml) and, from
# Jazzy on, the type description service.
NODE_SERVICES = ('~/describe_parameters', '~/get_parameter_types', '~/get_parameters',
                 '~/list_parameters', '~/set_parameters', '~/set_parameters_atomically',
                 '~/get_type_description')
# Services a node answers besides those (saw_ros/ros/nodes/simulator.py, player.py).
OWN_SERVICES: Dict[str, Tuple[str, ...]] = {
    'simulator': ('~/reset',),
    'player': ('~/pause', '~/resume', '~/toggle_paused', '~/is_paused', '~/play_next'),
}
# Nodes that follow the simulator's parameters: they call its get_parameters.
FOLLOWS_SIMULATOR = ('camera', 'comparison')
SIMULATOR_GET_PARAMETERS = '/simulator/get_parameters'
# The nodes that stand in for a publisher of the table in a replay: the player publishes what a
# bag recorded and /clock, the video source a real camera's frames (not rows of their own).
STAND_INS: Dict[str, Tuple[str, ...]] = {
    'player': tuple(topics.recorded_topics()) + (topics.CLOCK,),
    'video_source': (topics.IMAGE, topics.CAMERA_INFO, topics.CLOCK),
}


def nodes() -> List[str]:
    """Return every node of ours the table names, then the stand-ins, in a stable order."""
    named: List[str] = []
    for t in topics.TOPICS + topics.RCL_TOPICS:
        for n in t.publisher.split(', ') + list(topics.subscribers(t)):
            if n and n != 'every node' and n not in named:
                named.append(n)
    return named + [n for n in STAND_INS if n not in named]


def published(node: str) -> List[str]:
    """Return the topics ``node`` publishes: the table's, a stand-in's, and rclpy's own."""
    names = [t.name for t in topics.published_by(node)] + list(STAND_INS.get(node, ()))
    return sorted(set(names) | {topics.ROSOUT, topics.PARAMETER_EVENTS})


def subscribed(node: str) -> List[str]:
    """Return the topics ``node`` subscribes to, by the table."""
    return sorted(t.name for t in topics.subscribed_by(node))


def _list(profile: ET.Element, kind: str, item: str, names: List[str], rule: str) -> None:
    if names:
        element = ET.SubElement(profile, kind, {rule: 'ALLOW'})
        for name in names:
            ET.SubElement(element, item).text = name


def policy() -> ET.Element:
    """Return the policy element: one enclave a node (module docstring)."""
    root = ET.Element('policy', {'version': VERSION})
    enclaves = ET.SubElement(root, 'enclaves')
    for node in nodes():
        enclave = ET.SubElement(enclaves, 'enclave', {'path': f'{ENCLAVE_PREFIX}/{node}'})
        profile = ET.SubElement(ET.SubElement(enclave, 'profiles'), 'profile',
                                {'ns': '/', 'node': node})
        _list(profile, 'topics', 'topic', published(node), 'publish')
        _list(profile, 'topics', 'topic', subscribed(node), 'subscribe')
        _list(profile, 'services', 'service',
              list(NODE_SERVICES) + list(OWN_SERVICES.get(node, ())), 'reply')
        _list(profile, 'services', 'service',
              [SIMULATOR_GET_PARAMETERS] if node in FOLLOWS_SIMULATOR else [], 'request')
    return root


def policy_xml() -> str:
    """Return the policy as the text of an XML file."""
    root = policy()
    ET.indent(root, '  ')
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, 'unicode') + '\n'
