#!/usr/bin/env python3
"""Fleet benchmark (issue 31): real rcand processes (the bundled sim robot, camera off, R2R over MQTT, each robot its
own name, Ed25519 key and loopback HTTP port) split over two mosquitto brokers bridged to each other by mosquitto's
own bridge (`connection` / `topic r2r/# both`). Measures, in this order:

  steady   messages/s through each broker ($SYS, sys_interval 1), per robot; each robot's idle CPU (/proc/<pid>/stat
           over a window) and RSS, and the totals - at every fleet size of --sizes (the fleet grows in place);
  moving   the same with every robot driving (what the fleet e-stop's trials start from);
  estop    a signed fleet e-stop (R2R `command` on r2r/broadcast) published at broker A -> the last sim drive at zero
           (the drive's own zero_since_us, read over HTTP after the trial; one machine, one monotonic clock);
  auction  a task auction opened by one robot that every other robot bids on: decided - bid deadline; then the
           re-award when the winner is SIGKILLed after bidding;
  down     broker A killed by PID: the same e-stop published at broker B, measured on B's robots; what A's robots do;
           A restarted: the time until its robots and the bridge are back.

Everything is started and stopped by PID, bound to 127.0.0.1, bounded by --timeout, and its temp dir removed.
  bench/fleet_bench.py --build build [--sizes 50,100,200] [--trials 20] [--phases steady,estop,auction,down]
"""
import argparse
import base64
import ctypes
import http.client
import json
import os
import random
import resource
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import uuid
from concurrent.futures import ThreadPoolExecutor

import yaml
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

OWNER = "rcand-dev-owner"  # the bundled config's development owner token (README)
SENDER = "fleet-ops"  # the operator's key that signs the fleet e-stop
CLK_TCK = os.sysconf("SC_CLK_TCK")
_libc = ctypes.CDLL("libc.so.6", use_errno=True)


def log(*parts):
    print(time.strftime("%H:%M:%S"), *parts, file=sys.stderr, flush=True)


def die_with_parent():  # a child the harness started never outlives it (PR_SET_PDEATHSIG)
    _libc.prctl(1, signal.SIGTERM)


def free_ports(count):
    socks = []
    for _ in range(count):
        s = socket.socket()
        s.bind(("127.0.0.1", 0))
        socks.append(s)
    ports = [s.getsockname()[1] for s in socks]
    for s in socks:
        s.close()
    return ports


def now_us():
    return time.clock_gettime_ns(time.CLOCK_MONOTONIC) // 1000  # the kernel's and the sim drive's clock


def pct(values, p):
    values = sorted(values)
    return values[int(p * (len(values) - 1))] if values else float("nan")


def load():
    return open("/proc/loadavg").read().split()[:3]


def http_json(port, method, path, body=None, timeout=10):
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout)
    try:
        headers = {"Authorization": "Bearer " + OWNER}
        if body is not None:
            headers["Content-Type"] = "application/json"
            body = json.dumps(body)
        conn.request(method, path, body=body, headers=headers)
        response = conn.getresponse()
        text = response.read()
        try:
            return response.status, json.loads(text)
        except ValueError:
            return response.status, {"raw": text.decode(errors="replace")}
    finally:
        conn.close()


def canonical(message):  # what message_auth.cpp signs: keys sorted, no whitespace (nlohmann dump())
    return json.dumps(message, sort_keys=True, separators=(",", ":"), ensure_ascii=False).encode()


def signed(key, source, type_, payload):
    message = {"header": {"version": "1.0", "timestamp": round(time.time(), 3), "source_id": source},
               "type": type_, "payload": payload}
    sig = base64.b64encode(key.sign(canonical(message))).decode()
    message["header"]["signature"] = {"key_id": source, "sig": sig}
    return json.dumps(message, separators=(",", ":"))


class Broker:
    def __init__(self, name, root, port, bridge_to=None, nice=0, bridge_topics=("r2r/# both 1",)):
        self.name, self.port, self.dir = name, port, os.path.join(root, "broker-" + name)
        self.nice = nice
        os.makedirs(self.dir)
        self.conf = os.path.join(self.dir, "mosquitto.conf")
        lines = [f"listener {port} 127.0.0.1", "allow_anonymous true", "persistence false", "sys_interval 1",
                 "max_connections -1", "set_tcp_nodelay true", "max_queued_messages 10000",
                 f"log_dest file {self.dir}/broker.log", "log_type error", "log_type warning", "log_type notice"]
        if os.geteuid() == 0:
            import pwd
            lines.insert(0, "user " + pwd.getpwuid(os.geteuid()).pw_name)
        if bridge_to:  # mosquitto's own bridge; nothing of it is ours
            lines += [f"connection bridge-{name}-{bridge_to.name}", f"address 127.0.0.1:{bridge_to.port}",
                      *["topic " + t for t in bridge_topics], "cleansession true", "try_private true", "notifications false",
                      "restart_timeout 1 5", "keepalive_interval 10"]
        open(self.conf, "w").write("\n".join(lines) + "\n")
        self.proc = None

    def start(self):
        def child():
            die_with_parent()
            os.nice(self.nice)
        self.proc = subprocess.Popen(["mosquitto", "-c", self.conf], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     stderr=open(os.path.join(self.dir, "stderr"), "a"), preexec_fn=child)
        deadline = time.time() + 10
        while time.time() < deadline:
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=0.5).close()
                return
            except OSError:
                if self.proc.poll() is not None:
                    raise RuntimeError(f"mosquitto {self.name} exited; see {self.dir}")
                time.sleep(0.05)
        raise RuntimeError(f"mosquitto {self.name} did not listen")

    def kill(self, sig=signal.SIGKILL):
        if self.proc and self.proc.poll() is None:
            os.kill(self.proc.pid, sig)
            self.proc.wait(timeout=10)
        self.proc = None

    def sys(self):
        """The broker's $SYS counters (retained; updated every sys_interval)."""
        topics = ["$SYS/broker/uptime", "$SYS/broker/messages/received", "$SYS/broker/messages/sent",
                  "$SYS/broker/publish/messages/received", "$SYS/broker/publish/messages/sent",
                  "$SYS/broker/clients/connected", "$SYS/broker/load/publish/received/1min",
                  "$SYS/broker/load/publish/sent/1min", "$SYS/broker/bytes/received", "$SYS/broker/bytes/sent"]
        args = ["mosquitto_sub", "-h", "127.0.0.1", "-p", str(self.port), "-v", "-W", "3", "-C", str(len(topics))]
        for t in topics:
            args += ["-t", t]
        out = subprocess.run(args, capture_output=True, text=True, timeout=10).stdout
        values = {}
        for line in out.splitlines():
            topic, _, value = line.partition(" ")
            try:
                values[topic.replace("$SYS/broker/", "")] = float(value.split()[0])
            except (ValueError, IndexError):
                pass
        return values

    def cpu_ticks(self):
        return proc_ticks(self.proc.pid) if self.proc else 0


def proc_ticks(pid):
    fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return int(fields[11]) + int(fields[12])  # utime + stime (fields 14 and 15 of stat)


def thread_ticks(pid):
    """{tid: (thread name, utime + stime)} of one process."""
    out = {}
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            stat = open(f"/proc/{pid}/task/{tid}/stat").read()
        except OSError:
            continue
        comm = stat[stat.index("(") + 1:stat.rindex(")")]
        fields = stat.rsplit(")", 1)[1].split()
        out[tid] = (comm, int(fields[11]) + int(fields[12]))
    return out


def proc_rss_kb(pid):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


class Robot:
    def __init__(self, index, name, port, broker, keyfile, origin):
        self.index, self.name, self.port, self.broker, self.keyfile, self.origin = index, name, port, broker, keyfile, origin
        self.proc = None
        self.dir = None

    @property
    def pid(self):
        return self.proc.pid


class Fleet:
    def __init__(self, args):
        self.args = args
        self.root = tempfile.mkdtemp(prefix="rcand-fleet-bench-")
        self.repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        self.build = os.path.abspath(args.build)
        self.robots, self.brokers, self.pub = [], [], {}
        self.pool = ThreadPoolExecutor(max_workers=32)
        self.results = {"load_start": load(), "cpus": os.cpu_count()}

    # ---------------------------------------------------------------- setup
    def keys(self, size):
        keydir = os.path.join(self.root, "keys")
        os.makedirs(keydir)
        self.names = [f"r{i:03d}" for i in range(size)]
        peers = []
        self.private = {}
        for name in self.names + [SENDER]:
            key = Ed25519PrivateKey.generate()
            self.private[name] = key
            path = os.path.join(keydir, name + ".pem")
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
            os.write(fd, key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                           serialization.NoEncryption()))
            os.close(fd)
            raw = key.public_key().public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
            peers.append({"name": name, "public_key": base64.b64encode(raw).decode(),
                          "role": "owner" if name == SENDER else "user"})
        self.peers = peers  # every robot enrolled; the operator's key may stop the fleet
        self.peers_file = os.path.join(keydir, "fleet-peers.yaml")  # the one fleet file every robot reads
        json.dump({"peers": peers}, open(self.peers_file, "w"), indent=1)  # JSON is YAML

    def start_brokers(self):
        pa, pb = free_ports(2)
        a = Broker("a", self.root, pa, nice=self.args.broker_nice)
        b = Broker("b", self.root, pb, bridge_to=a, nice=self.args.broker_nice,
                   bridge_topics=[t.strip() for t in self.args.bridge_topics.split(",")])
        self.brokers = [a, b]
        a.start()
        b.start()
        for broker in self.brokers:  # one long-lived publisher per broker: the publish time is the write
            self.pub[broker.name] = self.publisher(broker)

    def publisher(self, broker):
        return subprocess.Popen(["mosquitto_pub", "-h", "127.0.0.1", "-p", str(broker.port), "-t", "r2r/broadcast",
                                 "-q", "1", "-l", "-i", f"{SENDER}-{broker.name}"], stdin=subprocess.PIPE,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, text=True, preexec_fn=die_with_parent)

    def robot_config(self, robot):
        config = yaml.safe_load(open(os.path.join(self.repo, "config", "sim-rover.rcan.yaml")))
        config.pop("camera", None)  # camera off (and with it depth)
        caps = [c for c in config["rcan_protocol"]["capabilities"] if c != "vision"] + ["org.rcand.fleet"]
        config["rcan_protocol"]["capabilities"] = caps
        config["metadata"]["robot_name"] = robot.name
        config["metadata"]["robot_uuid"] = str(uuid.uuid4())
        rt = config["runtime"]
        rt["listen"] = {"address": "127.0.0.1", "port": robot.port}
        rt["plugin_paths"] = [os.path.join(self.build, "plugins")]
        rt["state_dir"] = os.path.join(robot.dir, "state")
        rt["auth"]["jwt_secret_file"] = os.path.join(self.repo, "config", "dev-jwt.secret")
        rt["swarm_file"] = os.path.join(robot.dir, "no-swarm.yaml")  # never the machine's /etc/rcand
        rt["logging"] = {"level": "warn"}
        rt["r2r"] = {"enabled": True, "udp_enabled": False, "ws_dial": False,
                     "mqtt": {"host": "127.0.0.1", "port": robot.broker.port, "keepalive_s": 10},
                     "private_key_file": robot.keyfile, "require_signatures": True,
                     "peers_file": self.peers_file,
                     "origin": {"x": robot.origin[0], "y": robot.origin[1], "heading_deg": 0},
                     "bid_window_ms": self.args.bid_window_ms, "status_interval_ms": 1000}
        return config

    def spawn(self, robot):
        robot.dir = os.path.join(self.root, robot.name)
        os.makedirs(robot.dir, exist_ok=True)
        path = os.path.join(robot.dir, "robot.rcan.yaml")
        json.dump(self.robot_config(robot), open(path, "w"), indent=1)  # JSON is YAML
        robot.proc = subprocess.Popen([os.path.join(self.build, "kernel", "rcand"), "--config", path],
                                      stdin=subprocess.DEVNULL, stdout=open(os.path.join(robot.dir, "stdout"), "w"),
                                      stderr=open(os.path.join(robot.dir, "stderr"), "w"), preexec_fn=die_with_parent)

    def healthy(self, robot, deadline):
        while time.time() < deadline:
            if robot.proc.poll() is not None:
                raise RuntimeError(f"{robot.name} exited: " + open(os.path.join(robot.dir, "stderr")).read()[-2000:])
            try:
                if http_json(robot.port, "GET", "/health", timeout=2)[0] == 200:
                    return
            except OSError:
                pass
            time.sleep(0.1)
        raise RuntimeError(f"{robot.name} not healthy")

    def grow(self, size):
        """Starts robots up to `size`, in batches, each batch waited for (/health) before the next."""
        start = len(self.robots)
        ports = free_ports(size - start)
        for i in range(start, size):
            broker = self.brokers[i % 2]
            self.robots.append(Robot(i, self.names[i], ports[i - start], broker,
                                     os.path.join(self.root, "keys", self.names[i] + ".pem"), (i % 20, i // 20)))
        t0 = time.time()
        for b in range(start, size, self.args.batch):
            batch = self.robots[b:min(size, b + self.args.batch)]
            for robot in batch:
                self.spawn(robot)
            deadline = time.time() + 120
            list(self.pool.map(lambda r: self.healthy(r, deadline), batch))
        log(f"{size} robots up ({size - start} started in {time.time() - t0:.1f} s), load {load()}")
        self.wait_connected()

    def alive(self):
        return [r for r in self.robots if r.proc and r.proc.poll() is None]

    def wait_connected(self, brokers=None, timeout=60):
        """Until each broker counts its robots (+2: the bridge and our publisher) as connected clients."""
        brokers = brokers or self.brokers
        deadline = time.time() + timeout
        while time.time() < deadline:
            ok = True
            for broker in brokers:
                mine = sum(1 for r in self.alive() if r.broker is broker)
                if broker.sys().get("clients/connected", 0) < mine + 2:
                    ok = False
            if ok:
                return time.time()
            time.sleep(0.5)
        raise RuntimeError("robots not all connected to their brokers")

    # ---------------------------------------------------------------- steady state
    def steady(self, size, moving=False):
        """The fleet at rest, or (`moving`) with every robot driving: what each robot and broker costs."""
        robots = self.alive()
        if moving:
            self.prepare(robots)
        time.sleep(self.args.settle)
        before_ticks = {r.name: proc_ticks(r.pid) for r in robots}
        before_threads = thread_ticks(robots[0].pid)
        before_brokers = [(b.sys(), b.cpu_ticks()) for b in self.brokers]
        t0 = time.monotonic()
        time.sleep(self.args.window)
        elapsed = time.monotonic() - t0
        after_ticks = {r.name: proc_ticks(r.pid) for r in robots}
        after_threads = thread_ticks(robots[0].pid)
        after_brokers = [(b.sys(), b.cpu_ticks()) for b in self.brokers]
        cpu = [(after_ticks[r.name] - before_ticks[r.name]) / CLK_TCK / elapsed * 100 for r in robots]
        rss = [proc_rss_kb(r.pid) / 1024 for r in robots]
        out = {"n": size, "moving": moving, "window_s": round(elapsed, 1), "load": load(), "brokers": {}}
        total_pub_in = total_pub_out = 0
        for broker, (s0, c0), (s1, c1) in zip(self.brokers, before_brokers, after_brokers):
            dt = max(1.0, s1.get("uptime", 0) - s0.get("uptime", 0))  # the counters' own interval
            rate = {k: (s1.get(k, 0) - s0.get(k, 0)) / dt for k in
                    ("messages/received", "messages/sent", "publish/messages/received", "publish/messages/sent",
                     "bytes/received", "bytes/sent")}
            rate["cpu_pct"] = (c1 - c0) / CLK_TCK / elapsed * 100
            rate["clients"] = s1.get("clients/connected")
            rate["rss_mb"] = proc_rss_kb(broker.proc.pid) / 1024
            out["brokers"][broker.name] = {k: round(v, 1) if isinstance(v, float) else v for k, v in rate.items()}
            total_pub_in += rate["publish/messages/received"]
            total_pub_out += rate["publish/messages/sent"]
        out["publish_in_per_robot"] = round(total_pub_in / size, 2)
        out["publish_out_per_robot"] = round(total_pub_out / size, 2)
        out["robot_cpu_pct"] = {"mean": round(sum(cpu) / len(cpu), 2), "p50": round(pct(cpu, 0.5), 2),
                                "max": round(max(cpu), 2), "total": round(sum(cpu), 1)}
        out["robot_rss_mb"] = {"mean": round(sum(rss) / len(rss), 1), "max": round(max(rss), 1),
                               "total": round(sum(rss), 0)}
        threads = {}
        for tid, (comm, ticks) in after_threads.items():
            spent = ticks - before_threads.get(tid, (comm, 0))[1]
            threads[comm] = threads.get(comm, 0) + spent / CLK_TCK / elapsed * 100
        out["one_robot_threads_cpu_pct"] = {k: round(v, 2) for k, v in sorted(threads.items(), key=lambda kv: -kv[1]) if v > 0}
        out["topics_seen_2s"] = self.topics_seen(self.brokers[0])
        log("moving" if moving else "steady", json.dumps(out))
        self.results.setdefault("moving" if moving else "steady", []).append(out)

    def topics_seen(self, broker):
        """What 2 s of r2r/# at `broker` carry, by topic family: shows where status goes (before/after issue 31)."""
        out = subprocess.run(["mosquitto_sub", "-h", "127.0.0.1", "-p", str(broker.port), "-t", "r2r/#", "-v", "-W", "2",
                              "-F", "%t %r"], capture_output=True, text=True, timeout=10).stdout
        families = {}
        for line in out.splitlines():
            topic, _, retained = line.partition(" ")
            family = "r2r/status/<name>" if topic.startswith("r2r/status/") else \
                ("r2r/broadcast" if topic == "r2r/broadcast" else "r2r/<name>")
            if retained.strip() == "1":
                family += " (retained)"
            families[family] = families.get(family, 0) + 1
        return families

    # ---------------------------------------------------------------- fleet e-stop
    def prepare(self, robots):
        """Clears and sets every robot moving (HTTP, in parallel)."""
        move = {"type": "move", "linear": 0.4, "angular": 0.0, "duration_ms": 60000}

        def one(r):
            for _ in range(3):  # a 423: a late copy of an earlier stop latched it between clear and move
                http_json(r.port, "POST", "/api/estop/clear")
                status, body = http_json(r.port, "POST", "/api/action", move)
                if status == 200:
                    return 0
                if status != 423:
                    break
                time.sleep(0.5)
            raise RuntimeError(f"{r.name}: move refused {status} {body}")
        list(self.pool.map(one, robots))

    def drive(self, r):
        status, body = http_json(r.port, "GET", "/api/drivers/drive0")
        return body.get("status", {})

    def publish(self, broker, reason):
        """The signed fleet stop on r2r/broadcast at `broker`; returns the monotonic time of the write."""
        kind = self.args.estop_type
        payload = {"type": kind, "reason": "fleet bench: " + reason} if kind == "estop" else {"type": kind}
        line = signed(self.private[SENDER], SENDER, "command", payload)
        # --publish-everywhere: the one signed message at every broker up (the copy the bridge brings is a replay,
        # dropped), as an operator who names every broker to `rcanctl fleet stop` would send it.
        targets = [broker] + ([b for b in self.brokers if b is not broker and b.proc] if self.args.publish_everywhere else [])
        t0 = now_us()
        for target in targets:
            self.pub[target.name].stdin.write(line + "\n")
            self.pub[target.name].stdin.flush()
        return t0

    def publish_rcanctl(self, broker, reason):
        """The same fleet stop sent by `rcanctl fleet stop` (a process started per stop: its start is measured)."""
        t0 = now_us()
        subprocess.run([os.path.join(self.build, "rcanctl", "rcanctl"), "fleet", "stop", "--mqtt",
                        f"127.0.0.1:{broker.port}", "--key", os.path.join(self.root, "keys", SENDER + ".pem"),
                        "--name", SENDER, "--reason", "fleet bench: " + reason], check=True, timeout=60,
                       stdout=subprocess.DEVNULL)
        return t0

    def estop_trials(self, broker, robots, label, trials_count=None, via_rcanctl=False):
        trials, stuck = [], []
        payload_type = self.args.estop_type
        spent = {}  # --thread-cpu: thread name -> ticks the robots spent in the second after each publish
        for k in range(trials_count or self.args.trials):
            self.prepare(robots)
            time.sleep(0.3)
            before = [thread_ticks(r.pid) for r in robots] if self.args.thread_cpu else []
            wall0 = time.time() * 1000
            t0 = (self.publish_rcanctl if via_rcanctl else self.publish)(broker, f"{label} trial {k}")
            time.sleep(self.args.settle_stop)
            for r, ticks in zip(robots, before):
                for tid, (comm, after) in thread_ticks(r.pid).items():
                    spent[comm] = spent.get(comm, 0) + after - ticks.get(tid, (comm, 0))[1]
            states = list(self.pool.map(self.drive, robots))
            waited = now_us()
            while any(st.get("moving") is not False for st in states) and now_us() - waited < self.args.stop_wait * 1e6:
                time.sleep(0.25)  # a late robot: read again (its halt time is its own record, not this read's)
                states = [st if st.get("moving") is False else self.drive(r) for r, st in zip(robots, states)]
            if payload_type == "estop":  # the latch record (wall ms) beside the drive's own halt time (monotonic us)
                latches = [http_json(r.port, "GET", "/api/estop")[1] for r in robots]
                unlatched = [r.name for r, e in zip(robots, latches) if not e.get("estopped")]
                if unlatched:
                    log(f"estop {label} trial {k}: {len(unlatched)} not latched, e.g. {unlatched[:5]}")
                latch_ms = [e["since_ms"] - wall0 for e in latches if e.get("estopped")]
            moving = [r.name for r, s in zip(robots, states) if s.get("moving") is not False]
            if moving:
                stuck.append((k, moving[:10], len(moving)))
                log(f"estop {label} trial {k}: {len(moving)} still moving, e.g. {moving[:5]}")
                continue
            zeros = [(s["zero_since_us"] - t0) / 1000 for s in states]
            by_broker = {b.name: max(z for r, z in zip(robots, zeros) if r.broker is b)
                         for b in self.brokers if any(r.broker is b for r in robots)}
            trials.append({"last_ms": max(zeros), "median_robot_ms": pct(zeros, 0.5), "first_ms": min(zeros),
                           "last_by_broker_ms": by_broker,
                           "last_latch_ms": max(latch_ms) if payload_type == "estop" and latch_ms else None})
        latched = sum(1 for r in robots if http_json(r.port, "GET", "/api/estop")[1].get("estopped"))
        last = [t["last_ms"] for t in trials]
        out = {"label": label, "broker": broker.name, "robots": len(robots), "trials_ok": len(trials),
               "trials_failed": len(stuck), "stuck": stuck[:3], "estop_type": payload_type,
               "latched_after_last_trial": latched, "load": load(),
               "last_at_zero_ms": {"p50": round(pct(last, 0.5), 2), "p99": round(pct(last, 0.99), 2),
                                   "max": round(max(last), 2) if last else None},
               "median_robot_ms_p50": round(pct([t["median_robot_ms"] for t in trials], 0.5), 2)}
        out["last_at_zero_by_broker_p50_ms"] = {
            name: round(pct([t["last_by_broker_ms"][name] for t in trials], 0.5), 2) for name in trials[0]["last_by_broker_ms"]
        } if trials else {}
        if spent:  # CPU ms per robot per e-stop, by thread name (the settle window after the publish)
            per = len(robots) * (trials_count or self.args.trials)
            out["thread_cpu_ms_per_robot"] = {c: round(t * 1000 / CLK_TCK / per, 3)
                                              for c, t in sorted(spent.items(), key=lambda kv: -kv[1]) if t > 0}
        latch = [t["last_latch_ms"] for t in trials if t["last_latch_ms"] is not None]
        if latch:  # wall clock, whole milliseconds
            out["last_latch_record_ms"] = {"p50": round(pct(latch, 0.5), 1), "p99": round(pct(latch, 0.99), 1),
                                           "max": round(max(latch), 1)}
        log("estop", json.dumps(out))
        self.results.setdefault("estop", []).append(out)
        return out

    # ---------------------------------------------------------------- auctions
    def auction(self):
        robots = self.alive()
        requester = robots[0]
        rows = []
        for k in range(self.args.auctions):
            target = random.choice(robots[1:])
            task = {"task_id": f"bench-{k}-{uuid.uuid4().hex[:6]}", "description": "fleet bench",
                    "required_capabilities": ["teleop"], "location": {"x": target.origin[0], "y": target.origin[1]},
                    "wait": True, "timeout_ms": 20000}
            status, result = http_json(requester.port, "POST", "/api/r2r/auction", task, timeout=30)
            answered = time.time()
            if status != 200:
                rows.append({"error": status, "body": str(result)[:300]})
                continue
            rows.append({"winner": result.get("winner"), "expected": target.name, "bids": len(result.get("bids", [])),
                         "state": result.get("state"), "elapsed_ms": result.get("elapsed_ms"),
                         "answer_minus_deadline_ms": round((answered - result.get("bid_deadline", answered)) * 1000, 1)})
        ok = [r for r in rows if "elapsed_ms" in r]
        over = [r["elapsed_ms"] - self.args.bid_window_ms for r in ok]
        out = {"robots": len(robots), "bid_window_ms": self.args.bid_window_ms, "auctions": len(rows),
               "decided": sum(1 for r in ok if r["state"] == "assigned"),
               "nearest_won": sum(1 for r in ok if r["winner"] == r["expected"]),
               "bids_min": min((r["bids"] for r in ok), default=0), "bids_max": max((r["bids"] for r in ok), default=0),
               "decided_minus_deadline_ms": {"p50": round(pct(over, 0.5), 1), "max": round(max(over), 1) if over else None},
               "http_answer_minus_deadline_ms_max": max((r["answer_minus_deadline_ms"] for r in ok), default=None),
               "errors": [r for r in rows if "error" in r][:3], "load": load()}
        log("auction", json.dumps(out))
        self.results["auction"] = out
        self.winners = {r.get("winner") for r in ok}

    def reaward(self):
        robots = self.alive()
        requester = robots[0]  # the victim: a robot that holds no task (a held task adds to its price)
        victim = next(r for r in robots[len(robots) // 2:] + robots[1:] if r.name not in getattr(self, "winners", ()))
        task_id = "bench-rescue-" + uuid.uuid4().hex[:6]
        task = {"task_id": task_id, "required_capabilities": ["teleop"],
                "location": {"x": victim.origin[0], "y": victim.origin[1]}, "wait": False}
        status, _ = http_json(requester.port, "POST", "/api/r2r/auction", task)
        t_open = time.time()
        deadline = time.time() + 10
        bid_seen = None
        while time.time() < deadline:
            doc = http_json(requester.port, "GET", f"/api/r2r/auction/{task_id}")[1]
            if any(b.get("bidder") == victim.name for b in doc.get("bids", [])):
                bid_seen = time.time()
                break
            time.sleep(0.02)
        os.kill(victim.pid, signal.SIGKILL)  # after bidding, before the award
        victim.proc.wait()
        killed = time.time()
        result = None
        while time.time() < killed + 20:
            doc = http_json(requester.port, "GET", f"/api/r2r/auction/{task_id}")[1]
            if doc.get("state") == "assigned":
                result = doc
                break
            time.sleep(0.05)
        assigned = time.time()
        out = {"robots": len(robots), "victim": victim.name, "open_status": status,
               "victim_bid_after_ms": round((bid_seen - t_open) * 1000, 1) if bid_seen else None,
               "winner": result.get("winner") if result else None, "round": result.get("round") if result else None,
               "excluded": result.get("excluded") if result else None,
               "victim_won_round_1": bool(result and victim.name in (result.get("excluded") or [])),
               "reawarded_after_kill_ms": round((assigned - killed) * 1000) if result else None,
               "reawarded_after_open_ms": round((assigned - t_open) * 1000) if result else None,
               "load": load()}
        log("reaward", json.dumps(out))
        self.results["reaward"] = out

    # ---------------------------------------------------------------- one broker down
    def broker_down(self):
        a, b = self.brokers
        a_robots = [r for r in self.alive() if r.broker is a]
        b_robots = [r for r in self.alive() if r.broker is b]
        self.pub["a"].stdin.close()
        self.pub["a"].wait(timeout=5)
        a.kill()  # by PID
        killed = time.time()
        time.sleep(1.0)
        out = self.estop_trials(b, b_robots, "broker A down, published at B")
        # A's robots: the fleet stop published at B cannot reach them (honestly: they are still moving). Their local
        # safety holds: each one's own stop (HTTP, in parallel) latches it.
        self.prepare(a_robots)
        self.publish(b, "broker A down: for A's robots")
        time.sleep(self.args.settle_stop)
        moving_a = sum(1 for r in a_robots if self.drive(r).get("moving"))

        def local_stop(r):
            t0 = now_us()
            status, _ = http_json(r.port, "POST", "/api/stop")
            s = self.drive(r)
            return {"status": status, "ms": (s["zero_since_us"] - t0) / 1000 if s.get("moving") is False else None}
        local = list(self.pool.map(local_stop, a_robots))
        a.start()
        restarted = time.time()
        self.pub["a"] = self.publisher(a)
        back = self.wait_connected([a, b], timeout=90)
        self.results["down"] = {"a_robots": len(a_robots), "b_robots": len(b_robots), "estop_at_b": out,
                                "a_local_http_stop": {"stopped": sum(1 for x in local if x["ms"] is not None),
                                                      "of": len(local),
                                                      "max_ms": max((x["ms"] for x in local if x["ms"] is not None), default=None)},
                                "a_robots_still_moving_after_a_stop_at_b": moving_a, "a_down_s": round(restarted - killed, 1),
                                "a_robots_and_bridge_back_after_s": round(back - restarted, 1), "load": load()}
        log("down", json.dumps(self.results["down"]))
        # And a fleet stop at A once it is back reaches everyone again (through the bridge for B's robots).
        self.estop_trials(a, self.alive(), "after A restarted, published at A")

    # ---------------------------------------------------------------- teardown
    def close(self):
        procs = [p for p in self.pub.values()] + [r.proc for r in self.robots if r.proc]
        for p in procs:
            if p.poll() is None:
                p.terminate()
        deadline = time.time() + 15
        for p in procs:
            try:
                p.wait(timeout=max(0.1, deadline - time.time()))
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        for broker in self.brokers:
            broker.kill(signal.SIGTERM)
        self.pool.shutdown(wait=False, cancel_futures=True)
        if self.args.keep:
            log("kept", self.root)
        else:
            shutil.rmtree(self.root, ignore_errors=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--build", default="build")
    parser.add_argument("--sizes", default="50,100,200")
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--auctions", type=int, default=10)
    parser.add_argument("--phases", default="steady,estop,auction,reaward,down",
                        help="any of steady,moving,estop,auction,reaward,down (moving: steady with every robot driving)")
    parser.add_argument("--estop-type", default="estop", help="the command payload type: estop (fleet e-stop) or stop")
    parser.add_argument("--rcanctl-trials", type=int, default=0,
                        help="also this many e-stop trials sent by `rcanctl fleet stop` (its process start included)")
    parser.add_argument("--bid-window-ms", type=int, default=1000)
    parser.add_argument("--batch", type=int, default=20)
    parser.add_argument("--settle", type=float, default=5.0, help="s after a fleet size is up, before its window")
    parser.add_argument("--window", type=float, default=20.0, help="steady-state window, s")
    parser.add_argument("--settle-stop", type=float, default=1.0, help="s after a publish before reading the drives")
    parser.add_argument("--broker-nice", type=int, default=0,
                        help="the brokers' nice value (negative: a stand-in for brokers on machines of their own)")
    parser.add_argument("--bridge-topics", default="r2r/# both 1",
                        help="the bridge's topic lines, comma-separated (mosquitto.conf `topic`)")
    parser.add_argument("--publish-everywhere", action="store_true",
                        help="e-stop: publish the one signed stop at every broker that is up, not only at A")
    parser.add_argument("--thread-cpu", action="store_true",
                        help="e-stop: each thread's CPU in the settle window after a publish, per robot (reads /proc)")
    parser.add_argument("--stop-wait", type=float, default=10.0, help="s more for a late robot before a trial fails")
    parser.add_argument("--timeout", type=int, default=1500, help="total bound, s")
    parser.add_argument("--json", help="write the results here")
    parser.add_argument("--keep", action="store_true", help="keep the temp dir (logs)")
    args = parser.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    phases = set(args.phases.split(","))

    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))  # a broker holds one socket per robot

    def on_timeout(*_):
        raise TimeoutError(f"fleet bench: over its {args.timeout} s bound")
    signal.signal(signal.SIGALRM, on_timeout)
    signal.signal(signal.SIGTERM, on_timeout)
    signal.alarm(args.timeout)

    fleet = Fleet(args)
    rc = 0
    try:
        fleet.keys(max(sizes))
        fleet.start_brokers()
        for size in sizes:
            fleet.grow(size)
            if "steady" in phases:
                fleet.steady(size)
            if "moving" in phases:
                fleet.steady(size, moving=True)
        if "auction" in phases:  # first: before any trial moves the robots off their origins
            fleet.auction()
        if "reaward" in phases:
            fleet.reaward()
        if "estop" in phases:
            fleet.estop_trials(fleet.brokers[0], fleet.alive(), "published at A")
            if args.rcanctl_trials:
                fleet.estop_trials(fleet.brokers[0], fleet.alive(), "rcanctl fleet stop at A", args.rcanctl_trials, True)
        if "down" in phases:
            fleet.broker_down()
    except Exception as error:  # noqa: BLE001 - reported, then everything is cleaned up
        log("FAILED:", repr(error))
        rc = 1
    finally:
        signal.alarm(0)
        fleet.close()
    fleet.results["load_end"] = load()
    text = json.dumps(fleet.results, indent=1)
    print(text)
    if args.json:
        open(args.json, "w").write(text)
    return rc


if __name__ == "__main__":
    sys.exit(main())
