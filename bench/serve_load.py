#!/usr/bin/env python3
"""The field station under load: 20 clients on the loopback address reading the API and
following a layer's processing live, while that layer processes.

A small synthetic site (strata synth, 1 stage; --photos, --width) is made into two
identical projects: one is processed by `strata process` (the command line's products),
the other is served by `strata serve` and processed through the API while N clients
(default 20) each follow the job's Server-Sent Events and, in a loop, read the API
routes the pages read (site, units, relations, layers, the layer with its verdict, jobs,
markers, finds). Measured: every request's latency (ms, from sending to the last byte),
errors (any status but 200, any exception), events received per follower, and whether
the served layer's records and products equal the command line's: the alignment's
figures of `process --json` and the DTM's bytes.

Usage: bench/serve_load.py [--clients 20] [--photos 12] [--width 800] [--keep DIR]
Writes bench/results/<UTC time>-serve_load.json and prints it. Exit status 1 when a
request failed or the products differ.
"""
import argparse, datetime, hashlib, json, os, re, shutil, statistics, subprocess, sys, tempfile, threading, time
import http.client

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STRATA = os.environ.get("STRATA_BIN") or os.path.join(ROOT, os.environ.get("STRATA_BUILD_DIR", "build"), "src", "cli", "strata")
READS = ["/api/site", "/api/units", "/api/relations", "/api/layers", "/api/layers/L1", "/api/jobs", "/api/markers",
         "/api/finds"]


def strata(*args, capture=False):
    r = subprocess.run([STRATA, "-q", *args], check=True, text=True, capture_output=capture)
    return r.stdout


def make_project(site, data):
    strata("init", site, "--crs", "EPSG:32636")
    strata("unit", "add", site, "101")
    strata("layer", "add", site, "L1", "--unit", "101")
    photos = sorted(os.path.join(data, "photos", "L1", f) for f in os.listdir(os.path.join(data, "photos", "L1")))
    strata("import", "photos", site, "--layer", "L1", *photos)
    with open(os.path.join(data, "gcp_list.txt")) as f:
        lines = f.read().splitlines()
    clicks = os.path.join(os.path.dirname(site), os.path.basename(site) + "_gcp.txt")
    with open(clicks, "w") as f:
        f.write("\n".join([lines[0]] + [l for l in lines[1:] if l.split()[5:6] and l.split()[5].startswith("L1_")]) + "\n")
    strata("import", "markers", site, clicks, "--format", "odm")
    strata("import", "markers", site, os.path.join(data, "markers.csv"))


def percentile(values, q):
    s = sorted(values)
    return s[min(len(s) - 1, int(round(q * (len(s) - 1))))] if s else float("nan")


class Client(threading.Thread):
    """Reads the API in a loop until told to stop; every latency and error kept."""

    def __init__(self, port, stop):
        super().__init__(daemon=True)
        self.port, self.stop, self.latencies, self.errors = port, stop, [], []

    def run(self):
        conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=60)
        i = 0
        while not self.stop.is_set():
            path = READS[i % len(READS)]
            i += 1
            t = time.perf_counter()
            try:
                conn.request("GET", path)
                r = conn.getresponse()
                body = r.read()
                self.latencies.append((path, 1000 * (time.perf_counter() - t)))
                if r.status != 200:
                    self.errors.append(f"{path}: {r.status} {body[:200]!r}")
            except Exception as e:  # a dropped connection is an error too
                self.errors.append(f"{path}: {e!r}")
                conn.close()
                conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=60)


class Follower(threading.Thread):
    """Follows the job's Server-Sent Events to its end event."""

    def __init__(self, port, job):
        super().__init__(daemon=True)
        self.port, self.job, self.events, self.error, self.end = port, job, 0, None, None

    def run(self):
        try:
            conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=900)
            conn.request("GET", f"/api/jobs/{self.job}/events")
            r = conn.getresponse()
            kind = None
            for raw in r:
                line = raw.decode().rstrip("\n")
                if line.startswith("event: "):
                    kind = line[7:]
                    self.events += 1
                elif line.startswith("data: ") and kind == "end":
                    self.end = json.loads(line[6:])
        except Exception as e:
            self.error = repr(e)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clients", type=int, default=20)
    ap.add_argument("--photos", type=int, default=12)
    ap.add_argument("--width", type=int, default=800)
    ap.add_argument("--keep", help="work in this folder and keep it")
    args = ap.parse_args()
    work = args.keep or tempfile.mkdtemp(prefix="serve_load")
    os.makedirs(work, exist_ok=True)
    data, cli_site, api_site = (os.path.join(work, n) for n in ("data", "cli", "api"))
    for d in (data, cli_site, api_site):
        shutil.rmtree(d, ignore_errors=True)
    strata("synth", data, "--size", "small", "--stages", "1", "--photos", str(args.photos), "--width", str(args.width),
           "--seed", "5")
    make_project(cli_site, data)
    make_project(api_site, data)
    t = time.perf_counter()
    strata("process", cli_site, "--layer", "L1", capture=True)
    cli_seconds = time.perf_counter() - t

    server = subprocess.Popen([STRATA, "serve", api_site, "--listen", "127.0.0.1:0"], stdout=subprocess.PIPE,
                              stderr=open(os.path.join(work, "serve.err"), "w"), text=True)
    port = int(re.search(r"127\.0\.0\.1:(\d+)/", server.stdout.readline()).group(1))
    conn = http.client.HTTPConnection("127.0.0.1", port)
    conn.request("GET", "/api/session")
    token = json.loads(conn.getresponse().read())["csrf_token"]
    stop = threading.Event()
    clients = [Client(port, stop) for _ in range(args.clients)]
    for c in clients:
        c.start()
    t = time.perf_counter()
    conn.request("POST", "/api/layers/L1/process", body="{}", headers={"X-CSRF-Token": token,
                                                                       "Content-Type": "application/json"})
    r = conn.getresponse()
    job = json.loads(r.read())["id"]
    followers = [Follower(port, job) for _ in range(args.clients)]
    for f in followers:
        f.start()
    for f in followers:
        f.join()
    api_seconds = time.perf_counter() - t
    stop.set()
    for c in clients:
        c.join()
    server.terminate()
    server.wait(timeout=60)

    latencies = [ms for c in clients for _, ms in c.latencies]
    by_route = {}
    for c in clients:
        for path, ms in c.latencies:
            by_route.setdefault(path, []).append(ms)
    errors = [e for c in clients for e in c.errors] + [f"follower: {f.error}" for f in followers if f.error]
    ends = [f.end["state"] if f.end else None for f in followers]
    cli_json = json.loads(strata("process", cli_site, "--layer", "L1", "--json", capture=True))
    api_json = json.loads(strata("process", api_site, "--layer", "L1", "--json", capture=True))
    keys = ["images_registered", "points", "observations", "reprojection_rmse_px", "cameras", "control_rmse",
            "check_rmse", "markers"]
    same_figures = all(cli_json[k] == api_json[k] for k in keys)

    def sha(site):
        with open(os.path.join(site, "products", "L1", "dtm.tif"), "rb") as f:
            return hashlib.sha256(f.read()).hexdigest()

    same_dtm = sha(cli_site) == sha(api_site)
    result = {
        "when": datetime.datetime.utcnow().strftime("%Y%m%dT%H%M%SZ"),
        "clients": args.clients,
        "photos": args.photos,
        "width": args.width,
        "requests": len(latencies),
        "errors": len(errors),
        "error_samples": errors[:5],
        "latency_ms": {"p50": percentile(latencies, 0.5), "p95": percentile(latencies, 0.95),
                       "max": max(latencies) if latencies else None},
        "latency_p95_ms_by_route": {p: percentile(v, 0.95) for p, v in sorted(by_route.items())},
        "events_per_follower": {"min": min(f.events for f in followers), "max": max(f.events for f in followers)},
        "followers_ended": ends.count("done"),
        "process_s": {"cli_alone": round(cli_seconds, 1), "api_under_load": round(api_seconds, 1)},
        "same_figures_as_cli": same_figures,
        "same_dtm_as_cli": same_dtm,
    }
    os.makedirs(os.path.join(ROOT, "bench", "results"), exist_ok=True)
    out = os.path.join(ROOT, "bench", "results", f"{result['when']}-serve_load.json")
    with open(out, "w") as f:
        json.dump(result, f, indent=2)
    print(json.dumps(result, indent=2))
    print(f"written to {out}", file=sys.stderr)
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    ok = not errors and same_figures and same_dtm and ends.count("done") == len(followers)
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
