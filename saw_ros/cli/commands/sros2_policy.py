"""
The SROS2 access-control policy of the saw_ros nodes, from the topic table.

One enclave /saw_ros/<node> a node, allowing exactly the topics the table says it publishes and
reads, its parameter services, and the calls it makes (docs/security.md). For a ROS 2 install
whose DDS has the security plugins:
  saw-ros sros2-policy --out saw_ros.policy.xml
  ros2 security create_keystore keys
  ros2 security create_enclave keys /saw_ros/simulator     # and each other node's enclave
  ros2 security create_permission keys /saw_ros/simulator saw_ros.policy.xml
then run each node with --ros-args --enclave /saw_ros/<node> and ROS_SECURITY_KEYSTORE=keys,
ROS_SECURITY_ENABLE=true, ROS_SECURITY_STRATEGY=Enforce.
"""
from pathlib import Path

from saw_ros.cli.errors import UserError

NAME = 'sros2-policy'
HELP = 'write the SROS2 access-control policy of our nodes, from the topic table'


def add_arguments(p):
    p.add_argument('--out', type=Path, default=None,
                   help='policy XML file to write (default: print it)')


def run(args):
    from saw_ros.interface.sros2_policy import policy_xml
    text = policy_xml()
    if args.out is None:
        print(text, end='')
        return 0
    try:
        args.out.write_text(text, encoding='utf-8')
    except OSError as exc:
        raise UserError(f'--out {args.out}: cannot write: {exc.strerror or exc}') from None
    print(f'wrote {args.out}')
    return 0
