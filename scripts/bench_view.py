"""Lockstep speed with the live view: no view, view with no client, view with a client
reading /swarm/states and /world/markers.  Run side by side, in turns, on one domain.

    .venv/bin/python scripts/bench_view.py [SCENARIO] [--duration 40] [--rounds 2]
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import threading
from pathlib import Path

SWARM = str(Path(sys.executable).parent / 'swarm')
FINISH = re.compile(r'finished t=\S+ \((\d+) steps\) in ([\d.]+) s \(([\d.]+) steps/s\)')


def client(url, stop, counts):
    from websockets.sync.client import connect
    with connect(url, subprotocols=['foxglove.sdk.v1', 'foxglove.websocket.v1'], max_size=None) as ws:
        chans, subscribed = {}, False
        while not stop.is_set():
            try:
                msg = ws.recv(timeout=0.2)
            except TimeoutError:
                continue
            except Exception:
                return
            if isinstance(msg, str):
                m = json.loads(msg)
                if m['op'] == 'advertise':
                    chans.update({c['topic']: c['id'] for c in m['channels']})
                if not subscribed and {'/swarm/states', '/world/markers'} <= set(chans):
                    ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
                        {'id': 1, 'channelId': chans['/swarm/states']},
                        {'id': 2, 'channelId': chans['/world/markers']}]}))
                    subscribed = True
            elif msg[0] == 1:
                counts[msg[1]] = counts.get(msg[1], 0) + 1


def one(scenario, duration, mode):
    args = [SWARM, 'run', scenario, '--duration', str(duration), '--no-figure',
            '--out', f'/tmp/bench_view_{os.getpid()}']
    if mode != 'none':
        args += ['--foxglove', '0']
    p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1)
    stop, counts, speed = threading.Event(), {}, None
    for line in p.stdout:
        if mode == 'client' and 'serving on ws://' in line:
            url = line.split('serving on ')[1].split()[0]
            threading.Thread(target=client, args=(url, stop, counts), daemon=True).start()
        m = FINISH.search(line)
        if m:
            speed = float(m.group(3))
    p.wait()
    stop.set()
    return speed, counts.get(1, 0), counts.get(2, 0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('scenario', nargs='?', default='homotopy_global')
    ap.add_argument('--duration', type=float, default=40.0)
    ap.add_argument('--rounds', type=int, default=2)
    a = ap.parse_args()
    rows = {'none': [], 'view': [], 'client': []}
    for _ in range(a.rounds):
        for mode in rows:
            rows[mode].append(one(a.scenario, a.duration, mode))
            print(mode, rows[mode][-1], flush=True)
    print(f'| set-up ({a.scenario}, lockstep, {a.duration:g} s) | steps/s per round '
          '| states / marker arrays to the client |')
    print('|---|---|---|')
    for mode, rs in rows.items():
        label = {'none': 'no view', 'view': '--foxglove, no client',
                 'client': '--foxglove, client on states + markers'}[mode]
        print(f'| {label} | {", ".join(f"{s:.0f}" for s, _, _ in rs)} | '
              f'{", ".join(f"{n1} / {n2}" for _, n1, n2 in rs) if mode == "client" else "-"} |')


if __name__ == '__main__':
    main()
