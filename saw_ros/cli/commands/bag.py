"""
Inspect and record bags (rosbag2 directories with MCAP storage).

  saw-ros bag info BAG        what ``ros2 bag info`` shows: files, size, duration, start/end,
                              messages, and per topic type, count, rate and serialisation;
                              an unfinished file (recorder killed) is read up to its last
                              complete chunk (exit 0, "State: unfinished"); damaged bytes (a
                              chunk failing its CRC...) are an error (exit 1) naming each
                              damaged chunk, unless --salvage: then the rest is listed (exit 0)
  saw-ros bag record [...]    run the recorder node until Ctrl-C (same as
                              ``ros2 run saw_ros recorder``; see docs/bags.md)
  saw-ros bag play BAG [...]  run the player node on BAG
  saw-ros bag reindex BAG     an unfinished bag (recorder killed, copy cut short) made a
                              finished one that every MCAP reader opens: summary, indexes and
                              metadata.yaml (``ros2 bag reindex``); the original is kept
  saw-ros bag video BAG [-o camera.mp4]
                              the camera frames of a recording (its compressed stream, or
                              the raw one) as a video you can watch or track, at the rate
                              their stamps give
"""
from __future__ import annotations

import datetime
import os
import subprocess
import sys

from saw_ros.cli.checks import number, output_file, VIDEO_SUFFIXES
from saw_ros.cli.errors import UserError

HELP = 'bag info / record / play / video / reindex (rosbag2-compatible MCAP bags)'


def add_arguments(p):
    sub = p.add_subparsers(dest='bag_command', metavar='ACTION', required=True)
    info = sub.add_parser('info', help='summarise a bag like ros2 bag info')
    info.add_argument('bag', help='bag directory (or .mcap file)')
    info.add_argument('--salvage', action='store_true',
                      help='read around damaged chunks and list what was skipped (exit 0)')
    rec = sub.add_parser('record', help='record topics until Ctrl-C')
    rec.add_argument('topics', nargs='*', help='topics (default: msg_config/record_topics.yaml)')
    rec.add_argument('-o', '--output', default='', help='bag directory (must not exist)')
    rec.add_argument('--label', default='default', help='what, for the default directory name')
    play = sub.add_parser('play', help='play a bag onto its topics, with /clock')
    play.add_argument('bag')
    play.add_argument('-r', '--rate', type=float, default=1.0, help='speed factor')
    reindex = sub.add_parser('reindex', help='make an unfinished bag (recorder killed, copy '
                             'cut short) a finished one, as ros2 bag reindex')
    reindex.add_argument('bag', help='bag directory')
    video = sub.add_parser('video', help="write a recording's camera frames to an .mp4")
    video.add_argument('bag')
    video.add_argument('-o', '--output', default='camera.mp4', help='video file (camera.mp4)')
    video.add_argument('--topic', default='', help='image topic (default: the compressed '
                       'camera stream if recorded, else the raw one)')


def _stamp(ns) -> str:
    if ns is None:
        return 'n/a'
    when = datetime.datetime.fromtimestamp(ns / 1e9)
    return (f'{when:%b %d %Y %H:%M:%S}.{ns % 1_000_000_000:09d} '
            f'({ns // 1_000_000_000}.{ns % 1_000_000_000:09d})')


def _size(n: int) -> str:
    size = float(n)
    for unit in ('B', 'KiB', 'MiB', 'GiB'):
        if size < 1024 or unit == 'GiB':
            return f'{size:.1f} {unit}' if unit != 'B' else f'{n} B'
        size /= 1024
    return str(n)


def format_info(info: dict) -> str:
    lines = [f'Files:             {", ".join(info["files"])}',
             f'Bag size:          {_size(info["size"])}',
             f'Storage id:        {info["storage"]}',
             f'Duration:          {info["duration"] / 1e9:.9f}s',
             f'Start:             {_stamp(info["start"])}',
             f'End:               {_stamp(info["end"])}',
             f'Messages:          {info["messages"]}']
    if info.get('damage'):
        total = info.get('expected_messages')
        of = f' of {total}' if total is not None else ''
        lines.append(f'State:             DAMAGED, salvaged: {info["messages"]}{of} messages '
                     'read, '
                     f'{len(info["damage"])} damaged place(s) skipped')
        lines += [f'Damaged:           {d.describe()}' for d in info['damage']]
    if not info['complete']:
        cut = info.get('unread_bytes', 0)
        lines.append('State:             unfinished file (recorder killed?): read up to its last '
                     'complete record' + (f'; the last {cut} bytes (an incomplete record) not read'
                                          if cut else ''))
        if info.get('shortfall'):
            lines.append(f'Missing:           {info["shortfall"]}')
    if not info['has_metadata_yaml']:
        lines.append('metadata.yaml:     missing (read from the MCAP file)')
    topics = sorted(info['topics'].values(), key=lambda t: t.name)
    label = 'Topic information: '
    for t in topics:
        lines.append(f'{label}Topic: {t.name} | Type: {t.type} | Count: {t.count} | '
                     f'Rate: {t.rate:.1f} Hz | Serialization Format: {t.serialization_format}')
        label = ' ' * len(label)
    return '\n'.join(lines)


def _node(name, params):
    from saw_ros.graph.process import node_command
    argv = node_command(name, params=params)
    try:
        return subprocess.call(argv)
    except KeyboardInterrupt:
        return 0


IMAGE_TYPES = ('sensor_msgs/msg/Image', 'sensor_msgs/msg/CompressedImage')


def _open(bag):
    """Return a BagReader of ``bag``; a UserError (one line) when it is not a bag."""
    from saw_ros.bag.reader import BagReader, BagReadError
    try:
        reader = BagReader(bag)
        reader.info()           # the reader opens lazily: reading its summary finds a non-bag
    except BagReadError as exc:
        raise UserError(str(exc)) from None
    return reader


def _check_topic_name(name: str) -> None:
    """Refuse a topic name ROS would refuse, before the recorder starts (rcl's rules, no rclpy)."""
    from saw_ros.interface.names import topic_name_problem
    problem = topic_name_problem(name)
    if problem is not None:
        raise UserError(f'topic {name!r}: not a valid ROS topic name ({problem})')


def run(args):
    if args.bag_command == 'info':
        from saw_ros.bag.reader import BagDamagedError, BagReader, BagReadError
        try:
            print(format_info(BagReader(args.bag, salvage=args.salvage).info()))
        except BagDamagedError as exc:
            print(f'saw-ros bag: error: {exc}', file=sys.stderr)
            return 1
        except BagReadError as exc:
            raise UserError(str(exc)) from None
        return 0
    if args.bag_command == 'record':
        params = {'label': args.label}
        if args.output:
            if os.path.lexists(args.output):
                raise UserError(f'{args.output} exists already (a recording is never overwritten)')
            output_file(args.output, '-o')
            params['output'] = args.output
        for name in args.topics:
            _check_topic_name(name)
        if args.topics:
            params['topics'] = '[' + ','.join(args.topics) + ']'
        return _node('recorder', params)
    if args.bag_command == 'play':
        if not os.path.exists(args.bag):
            raise UserError(f'no bag at {args.bag}')
        # The player's own range for its rate (its spec lives in the ros layer, above cli's
        # reach: tests/packaging/test_layers.py).
        number(args.rate, '--rate', '', 0.0, None, low_open=True,
               description='speed factor: 1 = the recorded timing')
        _open(args.bag)                 # not a bag: said here, not by the player's FATAL line
        return _node('player', {'bag': os.path.abspath(args.bag), 'rate': float(args.rate)})
    if args.bag_command == 'reindex':
        from saw_ros.bag.reindex import reindex
        from saw_ros.bag.reader import BagReadError
        try:
            print(reindex(args.bag).describe())
        except (BagReadError, OSError) as exc:
            raise UserError(f'cannot reindex {args.bag}: {exc}') from None
        return 0
    if args.bag_command == 'video':
        from tqdm import tqdm

        from saw_ros.analysis.bag_frames import bag_video
        from saw_ros.bag.reader import BagReadError
        output_file(args.output, '-o', VIDEO_SUFFIXES)
        if args.topic:
            recorded = _open(args.bag).info()['topics']
            kind = recorded[args.topic].type if args.topic in recorded else None
            if kind is not None and kind not in IMAGE_TYPES:
                images = [t.name for t in recorded.values() if t.type in IMAGE_TYPES]
                raise UserError(f'--topic {args.topic} is not an image topic ({kind}); image '
                                f'topics recorded: {", ".join(images) or "none"}')
        # disable=None: the bar only on a terminal, not in logs or pipes.
        with tqdm(unit='frame', desc='bag video', file=sys.stderr, leave=False,
                  disable=None) as bar:
            def progress(done, total):
                bar.total = total
                bar.update(done - bar.n)
            try:
                frames, fps = bag_video(args.bag, args.output, args.topic or None, progress)
            except BagReadError as exc:
                raise UserError(str(exc)) from None
        print(f'{args.output}: {frames} frames at {fps:g} fps')
        return 0
    print(f'unknown action {args.bag_command}', file=sys.stderr)
    return 2
