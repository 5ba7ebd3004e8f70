"""Faithful stand-ins for ``ros2 node list``, ``ros2 node info``, ``ros2 param set`` and
``ros2 param describe`` (ROS 2 Jazzy); ros2cli is not in the pip wheels CI installs.

Read from ros2/ros2cli, branch jazzy (files and functions there):

- ``ros2cli/ros2cli/node/direct.py`` ``DirectNode.__init__``: ``rclpy.init()``, a hidden node
  ``_ros2cli_<pid>`` (``NODE_NAME_PREFIX``) with ``start_parameter_services=False`` and the
  overrides ``use_sim_time=False``, ``start_type_description_service=True``, spun with
  ``rclpy.spin_once`` until a timer of ``--spin-time`` (``DEFAULT_TIMEOUT``, 0.5 s) fired: the
  tool's only wait for discovery.  ``__exit__``: ``destroy_node()``, ``rclpy.try_shutdown()``.
  ``ros2cli/node/strategy.py`` ``NodeStrategy`` uses a DirectNode without a daemon (and on the
  first call, which only starts the daemon); a daemon that has run a while has seen at least as
  much, so these stand-ins are the tool at its least informed.
- ``ros2node/verb/list.py`` ``ListVerb.main`` with ``ros2node/api/__init__.py``
  ``get_node_names``: ONE ``get_node_names_and_namespaces()`` after the spin, hidden nodes
  (``_`` prefix) left out unless ``--all``, full name = namespace + ``/`` + name, sorted.
- ``ros2node/verb/info.py`` ``InfoVerb.main``: the node must be among ``get_node_names`` (else
  ``Unable to find node``), then ``api`` ``get_subscriber_info`` / ``get_publisher_info`` /
  ``get_service_server_info`` (``get_topics``: ``get_subscriber_names_and_types_by_node(name,
  namespace)`` and the like, once each, hidden names left out unless ``--include-hidden``).
- ``ros2topic/verb/list.py`` ``ListVerb.main`` with ``ros2topic/api/__init__.py``
  ``get_topic_names_and_types``: one ``get_topic_names_and_types()``, hidden topics
  (``topic_or_service_is_hidden``) left out unless ``--include-hidden-topics``.
- ``ros2param/verb/set.py`` ``SetVerb.main`` and ``ros2param/verb/describe.py``
  ``DescribeVerb.main``: ``wait_for_node`` (``ros2node/api``: ``ros2cli/helpers.py``
  ``wait_for``, a look every 0.1 s for ``--timeout`` = 1 s, without spinning) on one
  DirectNode, else ``Node not found``; then a SECOND DirectNode, and
  ``ros2param/api/__init__.py`` ``call_set_parameters`` / ``call_describe_parameters``: an
  ``rclpy.parameter_client.AsyncParameterClient``, ``wait_for_services(timeout_sec=5.0)`` (else
  RuntimeError), one request, ``rclpy.spin_until_future_complete`` (no time limit: here 60 s,
  a failure).  ``set`` types the text with ``rclpy.parameter.get_parameter_value``.

Each call makes a fresh rclpy Context, so a fresh DDS participant, as a new process of the
tool has; call it from a thread when the test's own executor must spin the nodes meanwhile.
As a script (a process of its own, in the environment given, e.g. a discovery server's):
``python ros2cli_verbs.py node list | topic list | node info NODE``, printing what the tool does.
"""
from __future__ import annotations

import contextlib
import os
import sys
import time

SPIN_TIME = 0.5          # ros2cli/node/direct.py DEFAULT_TIMEOUT
WAIT_PERIOD = 0.1        # ros2cli/helpers.py wait_for
NODE_TIMEOUT = 1.0       # ros2param/verb/set.py, describe.py: --timeout
SERVICE_TIMEOUT = 5.0    # ros2param/api/__init__.py: wait_for_services(timeout_sec=5.0)


class NodeNotFound(RuntimeError):
    """What ``ros2 param`` prints (``Node not found``) or ``ros2 node info`` (``Unable to find node``)."""


@contextlib.contextmanager
def direct_node(spin_time: float = SPIN_TIME):
    """ros2cli's ``DirectNode``: (node, executor) in a fresh Context, spun ``spin_time`` s."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    ctx = Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node(
        f'_ros2cli_{os.getpid()}', context=ctx, start_parameter_services=False,
        parameter_overrides=[Parameter('use_sim_time', value=False),
                             Parameter('start_type_description_service', value=True)],
        automatically_declare_parameters_from_overrides=True)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    try:
        reached = []
        timer = node.create_timer(spin_time, lambda: reached.append(True))
        while not reached:
            ex.spin_once()
        node.destroy_timer(timer)
        yield node, ex
    finally:
        ex.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def node_names(node, include_hidden=False) -> list:
    """ros2node/api ``get_node_names``: full names."""
    return [ns + ('' if ns.endswith('/') else '/') + nm for nm, ns in node.get_node_names_and_namespaces()
            if include_hidden or (nm and not nm.startswith('_'))]


def _split(full_name):
    """ros2node/api ``parse_node_name``: (name, namespace)."""
    full_name = full_name if full_name.startswith('/') else '/' + full_name
    ns, name = full_name.rsplit('/', 1)
    return name, ns or '/'


def _hidden(topic):
    return any(part.startswith('_') for part in topic.split('/'))


def node_list(include_hidden=False, spin_time=SPIN_TIME) -> list:
    """``ros2 node list [--all]``: the sorted full names."""
    with direct_node(spin_time) as (node, _):
        return sorted(node_names(node, include_hidden))


def node_info(full_name, include_hidden=False, spin_time=SPIN_TIME) -> dict:
    """``ros2 node info NODE``: {'subscribers': {topic: [types]}, 'publishers': {...}};
    `NodeNotFound` if the node is not in the graph the tool sees."""
    with direct_node(spin_time) as (node, _):
        if full_name not in node_names(node, include_hidden):
            raise NodeNotFound(f"Unable to find node '{full_name}'")
        name, ns = _split(full_name)
        subs = node.get_subscriber_names_and_types_by_node(name, ns)
        pubs = node.get_publisher_names_and_types_by_node(name, ns)
        services = node.get_service_names_and_types_by_node(name, ns)
    return {'subscribers': {t: list(ty) for t, ty in subs if include_hidden or not _hidden(t)},
            'publishers': {t: list(ty) for t, ty in pubs if include_hidden or not _hidden(t)},
            'services': {t: list(ty) for t, ty in services if include_hidden or not _hidden(t)}}


def topic_list(include_hidden=False, spin_time=SPIN_TIME) -> list:
    """``ros2 topic list [--include-hidden-topics]``: the topic names, in the graph's order."""
    from rclpy.topic_or_service_is_hidden import topic_or_service_is_hidden
    with direct_node(spin_time) as (node, _):
        return [t for t, _ in node.get_topic_names_and_types() if include_hidden or not topic_or_service_is_hidden(t)]


def _wait_for_node(full_name, timeout=NODE_TIMEOUT):
    """ros2node/api ``wait_for_node`` on a DirectNode (``NodeStrategy``)."""
    with direct_node() as (node, _):
        deadline = time.time() + timeout
        while full_name not in node_names(node):
            if time.time() > deadline:
                if full_name in node_names(node):
                    break
                raise NodeNotFound('Node not found')
            time.sleep(WAIT_PERIOD)


def _call(full_name, request):
    """The second DirectNode and ``ros2param/api`` ``call_*``: ``request(client)`` -> a future."""
    from rclpy.parameter_client import AsyncParameterClient
    with direct_node() as (node, ex):
        client = AsyncParameterClient(node, full_name)
        if not client.wait_for_services(timeout_sec=SERVICE_TIMEOUT):
            raise RuntimeError(f'Wait for service timed out waiting for parameter services for node {full_name}')
        future = request(client)
        ex.spin_until_future_complete(future, timeout_sec=60.0)
        response = future.result()
        if response is None:
            raise RuntimeError(f'Exception while calling service of node {full_name}: {future.exception()}')
        return response


def param_set(full_name, name, text):
    """``ros2 param set NODE NAME TEXT``: the one ``SetParametersResult`` (``successful``,
    ``reason``)."""
    from rcl_interfaces.msg import Parameter as ParameterMsg
    from rclpy.parameter import get_parameter_value
    _wait_for_node(full_name)
    msg = ParameterMsg(name=name, value=get_parameter_value(string_value=text))
    response = _call(full_name, lambda client: client.set_parameters([msg]))
    assert len(response.results) == 1
    return response.results[0]


def param_describe(full_name, names) -> list:
    """``ros2 param describe NODE NAME...``: the ``ParameterDescriptor`` s."""
    _wait_for_node(full_name)
    return list(_call(full_name, lambda client: client.describe_parameters(list(names) or None)).descriptors)


def main(argv) -> int:
    """``node list``, ``topic list`` or ``node info NODE``, printed as the tool prints them."""
    if argv[:2] == ['node', 'list']:
        print(*node_list(), sep='\n')
    elif argv[:2] == ['topic', 'list']:
        print(*topic_list(), sep='\n')
    elif argv[:2] == ['node', 'info'] and len(argv) == 3:
        try:
            info = node_info(argv[2])
        except NodeNotFound as err:
            print(err, file=sys.stderr)
            return 1
        print(argv[2])
        for key, title in (('subscribers', 'Subscribers'), ('publishers', 'Publishers'),
                           ('services', 'Service Servers')):
            print(f'  {title}:')
            for name, types in info[key].items():
                print(f'    {name}: {", ".join(types)}')
    else:
        print('usage: ros2cli_verbs.py node list | topic list | node info NODE', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
