#!/usr/bin/python3
"""The field station in a real browser: `strata serve` on a small synthetic site, driven
by headless Chromium through Debian's selenium and chromedriver. Nothing is mocked: the
pages (web/, embedded in the executable) talk to the real server, which records into a
real project and processes a real layer.

    /usr/bin/python3 tests/browser/field_station_test.py --strata build/src/cli/strata --scratch /tmp/fs-browser

The tests run in order (test_1_..., test_2_...: unittest's alphabetical order is the
flow), each one asserting on what the page shows. Screenshots go to SCRATCH/shots/.
"""

import argparse
import csv
import functools
import glob
import json
import os
import re
import selectors
import shutil
import signal
import subprocess
import sys
import threading
import time
import unittest
import urllib.error
import urllib.request

from selenium import webdriver
from selenium.common.exceptions import TimeoutException, WebDriverException
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys
from selenium.webdriver.support.ui import Select, WebDriverWait

STRATA = None   # path of the strata executable
SCRATCH = None  # scratch folder: data/, site/, shots/, chrome-profile/, server.log

XSS = '<script>window.__xss=1</script>topsoil'


def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--strata', required=True, help='the strata executable')
    parser.add_argument('--scratch', required=True, help='a scratch folder (its data/, site/, shots/ ... are replaced)')
    return parser.parse_known_args(argv)


def run_strata(*args, timeout=600):
    """Runs strata; fails the caller's test (AssertionError) on a non-zero exit code."""
    cmd = [STRATA, *args]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if p.returncode != 0:
        raise AssertionError(f'{" ".join(cmd)} exited {p.returncode}\nstdout:\n{p.stdout}\nstderr:\n{p.stderr}')
    return p


def tail(path, lines=40):
    try:
        with open(path, errors='replace') as f:
            return ''.join(f.readlines()[-lines:])
    except OSError as e:
        return f'(cannot read {path}: {e})'


# Browser console entries a step provokes on purpose: a refused request (400) is logged
# by Chromium as "Failed to load resource" at level SEVERE. A favicon 404 is tolerated.
def _allowed(entry, allowed):
    msg = entry.get('message', '')
    if 'favicon.ico' in msg and '404' in msg:
        return True
    return any(all(part in msg for part in a) for a in allowed)


def step(allowed_console=()):
    """Wraps a test: on failure prints the page's #message, the server's stderr tail and
    the browser console, and saves a screenshot; at the end fails on any SEVERE console
    entry that the step does not provoke on purpose (allowed_console: tuples of substrings)."""
    def wrap(fn):
        @functools.wraps(fn)
        def run(self):
            try:
                fn(self)
            except BaseException:
                self.diagnose(fn.__name__)
                raise
            self.check_console(fn.__name__, allowed_console)
        return run
    return wrap


class FieldStationTest(unittest.TestCase):
    server = None
    driver = None
    url = None

    # ---- the site, the server, the browser --------------------------------------------
    @classmethod
    def setUpClass(cls):
        cls.t0 = time.monotonic()
        os.makedirs(SCRATCH, exist_ok=True)
        for sub in ('data', 'site', 'shots', 'chrome-profile'):
            shutil.rmtree(os.path.join(SCRATCH, sub), ignore_errors=True)
        for f in ('gcp_L1.txt', 'server.log'):
            if os.path.exists(os.path.join(SCRATCH, f)):
                os.remove(os.path.join(SCRATCH, f))
        os.makedirs(os.path.join(SCRATCH, 'shots'))
        cls.data = os.path.join(SCRATCH, 'data')
        cls.site = os.path.join(SCRATCH, 'site')
        cls.shots = os.path.join(SCRATCH, 'shots')
        cls.server_log = os.path.join(SCRATCH, 'server.log')

        # Non-coded markers (chequered quadrants): the marker workspace is where they are
        # placed, and the guide's refinement to their centre of symmetry applies to them.
        run_strata('-q', 'synth', cls.data, '--size', 'small', '--stages', '1', '--photos', '12',
                   '--width', '800', '--seed', '5', '--marker-pattern', 'quadrant')
        run_strata('-q', 'init', cls.site, '--crs', 'EPSG:32636')

        cls.stderr_file = open(cls.server_log, 'w')
        cls.server = subprocess.Popen([STRATA, 'serve', cls.site, '--listen', '127.0.0.1:0'],
                                      stdout=subprocess.PIPE, stderr=cls.stderr_file, stdin=subprocess.DEVNULL)
        first = cls._first_line(cls.server.stdout, 30)
        prefix = f'strata serve: {cls.site} on '
        if not first.startswith('strata serve: ') or ' on http://127.0.0.1:' not in first:
            cls._stop_server()
            raise AssertionError(f'unexpected first line of strata serve: {first!r}\n{tail(cls.server_log)}')
        if not first.startswith(prefix):
            print(f'note: first line names the folder differently: {first!r}', file=sys.stderr)
        cls.url = first.split(' on ', 1)[1].split(' ', 1)[0]
        assert cls.url.endswith('/'), first
        print(f'\nserver: {cls.url} (stderr: {cls.server_log})', file=sys.stderr)
        # Whatever else the server prints on stdout is read, so its pipe never fills.
        threading.Thread(target=lambda: cls.server.stdout.read(), daemon=True).start()

        options = webdriver.ChromeOptions()
        for a in ('--headless=new', '--no-sandbox', '--disable-dev-shm-usage', '--disable-background-networking',
                  '--disable-component-update', '--disable-sync', '--no-first-run', '--window-size=1280,1000',
                  f'--user-data-dir={os.path.join(SCRATCH, "chrome-profile")}'):
            options.add_argument(a)
        options.set_capability('goog:loggingPrefs', {'browser': 'ALL'})
        try:
            cls.driver = webdriver.Chrome(service=Service('/usr/bin/chromedriver'), options=options)
        except Exception:
            cls._stop_server()
            raise
        cls.driver.set_script_timeout(30)

    @classmethod
    def _first_line(cls, stream, timeout):
        sel = selectors.DefaultSelector()
        sel.register(stream, selectors.EVENT_READ)
        buf = b''
        deadline = time.monotonic() + timeout
        fd = stream.fileno()
        while b'\n' not in buf:
            left = deadline - time.monotonic()
            if left <= 0 or not sel.select(left):
                cls._stop_server()
                raise AssertionError(f'strata serve printed no first line in {timeout} s\n{tail(cls.server_log)}')
            chunk = os.read(fd, 4096)
            if not chunk:
                code = cls.server.wait(5)
                raise AssertionError(f'strata serve exited {code} before its first line\n{tail(cls.server_log)}')
            buf += chunk
        sel.close()
        # The rest of buf (if any) is further stdout output and is not needed.
        return buf.split(b'\n', 1)[0].decode()

    @classmethod
    def _stop_server(cls):
        if not cls.server or cls.server.poll() is not None:
            return cls.server.returncode if cls.server else None
        cls.server.send_signal(signal.SIGTERM)
        try:
            return cls.server.wait(30)
        except subprocess.TimeoutExpired:
            cls.server.kill()
            cls.server.wait(10)
            return 'killed after 30 s without stopping on SIGTERM'

    @classmethod
    def tearDownClass(cls):
        code = cls._stop_server()
        if cls.driver:
            try:
                cls.driver.quit()
            except WebDriverException as e:
                print(f'driver.quit: {e}', file=sys.stderr)
        cls.stderr_file.close()
        print(f'\nstrata serve after SIGTERM: exit code {code}', file=sys.stderr)
        print(f'whole run: {time.monotonic() - cls.t0:.1f} s; screenshots in {cls.shots}', file=sys.stderr)
        if code != 0:
            raise AssertionError(f'strata serve after SIGTERM: exit code {code}, not 0\n{tail(cls.server_log)}')

    # ---- helpers -----------------------------------------------------------------------
    def js(self, script, *args):
        return self.driver.execute_script(script, *args)

    def wait(self, condition, timeout, what, poll=0.1):
        """Waits until condition(driver) is truthy; fails naming `what`."""
        try:
            return WebDriverWait(self.driver, timeout, poll_frequency=poll).until(condition)
        except TimeoutException:
            self.fail(f'after {timeout} s: {what}\n#message: {self.message()!r}')

    def message(self):
        try:
            return self.js("const m = document.getElementById('message'); return m ? m.textContent : '(no #message)';")
        except WebDriverException as e:
            return f'(cannot read #message: {e.msg})'

    def message_kind(self):
        return self.js("return document.getElementById('message').className;")

    def open(self, hash_, ready_css, timeout=30):
        """A fresh load of the page at #hash_, ready when ready_css is there and the page not busy."""
        self.driver.get('about:blank')
        self.driver.get(self.url + hash_)
        self.wait(lambda d: d.execute_script(
            "return document.querySelector(arguments[0]) !== null && !document.getElementById('page').hasAttribute('aria-busy');",
            ready_css), timeout, f'page {hash_}: {ready_css} shown')

    def form(self, form_id):
        return self.driver.find_element(By.ID, form_id)

    def fill(self, form, values):
        """Fills a form's controls by name; selects by value."""
        for name, value in values.items():
            c = form.find_element(By.NAME, name)
            if c.tag_name == 'select':
                Select(c).select_by_value(value)
            else:
                c.clear()
                c.send_keys(value)

    def rows(self, table_id):
        """The rows of a table as lists of cell texts (the 'None yet' row excluded)."""
        return self.js("""
            const t = document.getElementById(arguments[0]);
            if (!t) return null;
            return [...t.tBodies[0].rows].filter((r) => !r.classList.contains('empty'))
                .map((r) => [...r.cells].map((c) => c.textContent));""", table_id)

    def row(self, table_id, first_cell):
        for r in self.rows(table_id) or []:
            if r and r[0] == first_cell:
                return r
        return None

    def wait_row(self, table_id, first_cell, timeout=20):
        return self.wait(lambda d: self.row(table_id, first_cell), timeout,
                         f'#{table_id} has a row {first_cell}')

    def wait_message(self, predicate, timeout, what):
        return self.wait(lambda d: predicate(self.message(), self.message_kind()) and self.message(), timeout, what)

    def screenshot(self, name, full=True):
        """Saves SCRATCH/shots/NAME.png; full: the whole page (the window made as tall as it)."""
        path = os.path.join(self.shots, f'{name}.png')
        size = self.driver.get_window_size()
        try:
            if full:
                height = self.js('return Math.max(document.documentElement.scrollHeight, document.body.scrollHeight);')
                chrome = size['height'] - self.js('return window.innerHeight;')
                if height + chrome > size['height']:
                    self.driver.set_window_size(size['width'], min(int(height + chrome), 6000))
                    time.sleep(0.3)
            self.driver.save_screenshot(path)
        finally:
            if full:
                self.driver.set_window_size(size['width'], size['height'])
        print(f'screenshot: {path}', file=sys.stderr)
        return path

    def api(self, method, path, body=None):
        """The API as a script would use it (the CSRF token from /api/session); (status, parsed body)."""
        headers = {'Accept': 'application/json'}
        data = None
        if method == 'POST':
            with urllib.request.urlopen(self.url + 'api/session', timeout=30) as r:
                headers['X-CSRF-Token'] = json.load(r)['csrf_token']
            headers['Content-Type'] = 'application/json'
            data = json.dumps(body or {}).encode()
        req = urllib.request.Request(self.url + path.lstrip('/'), data=data, method=method, headers=headers)
        try:
            with urllib.request.urlopen(req, timeout=60) as r:
                return r.status, json.loads(r.read() or b'null')
        except urllib.error.HTTPError as e:
            return e.code, json.loads(e.read() or b'null')

    def diagnose(self, name):
        print(f'\n---- {name} failed ----', file=sys.stderr)
        try:
            print(f'url: {self.driver.current_url}', file=sys.stderr)
            print(f'#message: {self.message()!r}', file=sys.stderr)
            self.screenshot(f'failed_{name}', full=False)
        except Exception as e:  # the browser itself may be what failed
            print(f'(browser not readable: {e})', file=sys.stderr)
        print(f'server stderr, last lines ({self.server_log}):\n{tail(self.server_log)}', file=sys.stderr)
        print(f'server running: {self.server.poll() is None}', file=sys.stderr)
        try:
            for e in self.driver.get_log('browser'):
                print(f'console {e.get("level")}: {e.get("message")}', file=sys.stderr)
        except Exception:
            pass

    def check_console(self, name, allowed):
        entries = self.driver.get_log('browser')
        for e in entries:
            print(f'console [{name}] {e.get("level")}: {e.get("message")}', file=sys.stderr)
        severe = [e for e in entries if e.get('level') == 'SEVERE' and not _allowed(e, allowed)]
        if severe:
            self.fail('SEVERE browser console entries:\n' + '\n'.join(e.get('message', '') for e in severe))

    # ---- the flow ----------------------------------------------------------------------
    @step(allowed_console=[('/api/relations', 'status of 400')])
    def test_1_site_units_relations_matrix_layer(self):
        d = self.driver
        self.open('#/site', '#units-table')
        self.assertEqual(self.rows('units-table'), [], 'a new site shows no units')
        self.assertEqual(d.find_element(By.ID, 'site-crs').text, 'EPSG:32636')

        # Unit 101, its description a script: submitted with Enter in the description.
        form = self.form('unit-form')
        self.fill(form, {'code': '101', 'type': 'deposit', 'description': XSS})
        form.find_element(By.NAME, 'description').send_keys(Keys.ENTER)
        row = self.wait_row('units-table', '101')
        self.wait_message(lambda m, k: m == 'Unit 101 recorded.' and k == 'ok', 10, 'message "Unit 101 recorded."')
        self.assertEqual(row[1], 'deposit')
        self.assertEqual(row[2], XSS, 'the description is shown as the characters recorded')

        # Unit 102 with the button.
        form = self.form('unit-form')
        self.assertEqual(form.find_element(By.NAME, 'code').get_attribute('value'), '', 'the form is reset')
        self.fill(form, {'code': '102', 'type': 'cut', 'description': 'pit cut'})
        d.find_element(By.ID, 'add-unit').click()
        row = self.wait_row('units-table', '102')
        self.assertEqual(row[1:3], ['cut', 'pit cut'])
        self.assertEqual(len(self.rows('units-table')), 2)
        self.assertEqual(self.js('return typeof window.__xss;'), 'undefined', 'the description ran as a script')
        self.assertEqual(self.js("return document.querySelectorAll('#page script').length;"), 0)
        self.assertEqual(self.js("""return [...document.querySelectorAll('#site-counts li')]
                                      .find((li) => li.dataset.count === 'units').textContent;"""), '2 units')

        # Relation 101 above 102.
        form = self.form('relation-form')
        self.fill(form, {'a': '101', 'relation': 'above', 'b': '102'})
        d.find_element(By.ID, 'add-relation').click()
        self.wait(lambda d: d.find_elements(By.CSS_SELECTOR, '#relations-list li'), 20, '#relations-list shows a relation')
        items = d.find_elements(By.CSS_SELECTOR, '#relations-list li')
        self.assertEqual([i.text for i in items], ['101 above 102'])
        self.assertEqual((items[0].get_attribute('data-a'), items[0].get_attribute('data-relation'),
                          items[0].get_attribute('data-b')), ('101', 'above', '102'))
        self.wait_message(lambda m, k: k == 'ok' and '101 above 102' in m, 10, 'message: 101 above 102 recorded')

        # 102 above 101 would make the matrix cyclic: refused, naming the cycle.
        form = self.form('relation-form')
        self.fill(form, {'a': '102', 'relation': 'above', 'b': '101'})
        form.find_element(By.NAME, 'b').send_keys(Keys.ENTER)
        msg = self.wait_message(lambda m, k: k == 'error' and m, 20, 'an error in #message for 102 above 101')
        self.assertIn('cycle', msg.lower(), f'the refusal names the cycle: {msg!r}')
        invalid = self.js("""return [...document.querySelectorAll('#relation-form [aria-invalid="true"]')]
                               .map((e) => e.name);""")
        self.assertTrue(invalid, f'an input of the relation form is marked aria-invalid (message {msg!r})')
        print(f'cycle refused: {msg!r}; marked: {invalid}', file=sys.stderr)
        self.assertEqual([i.text for i in d.find_elements(By.CSS_SELECTOR, '#relations-list li')], ['101 above 102'])

        # The Harris matrix, drawn by Graphviz.
        state = self.wait(lambda d: d.execute_script("""
            if (document.getElementById('matrix-missing')) return 'missing';
            const i = document.getElementById('matrix-image');
            return i && i.complete && i.naturalWidth > 0 ? 'drawn' : null;"""), 20, 'the Harris matrix image loaded')
        if state == 'missing':
            self.fail('#matrix-missing shown: the server could not draw the Harris matrix (is Graphviz dot installed?): '
                      + d.find_element(By.ID, 'matrix-missing').text)
        w, h = self.js("const i = document.getElementById('matrix-image'); return [i.naturalWidth, i.naturalHeight];")
        self.assertGreater(w, 0)
        self.assertGreater(h, 0)
        src = d.find_element(By.ID, 'matrix-image').get_attribute('src')
        with urllib.request.urlopen(src, timeout=30) as r:
            svg = r.read().decode()
        self.assertIn('101', svg)
        self.assertIn('102', svg)

        # Layer L1 of unit 101.
        form = self.form('layer-form')
        self.wait(lambda d: d.execute_script(
            "return [...document.querySelectorAll('#layer-form select[name=unit] option')].some((o) => o.value === '101');"),
            10, 'the layer form offers unit 101')
        self.fill(form, {'name': 'L1', 'unit': '101'})
        d.find_element(By.ID, 'add-layer').click()
        row = self.wait_row('layers-table', 'L1')
        self.assertEqual(row[1], '101')
        self.assertEqual(row[3], '0', 'no photos yet')
        self.wait(lambda d: (self.row('units-table', '101') or [''] * 4)[3] == 'L1', 10, 'unit 101 lists layer L1')
        self.assertEqual(d.find_element(By.CSS_SELECTOR, '#layers-table a').get_attribute('href'), self.url + '#/layer/L1')
        self.screenshot('site')

    @step(allowed_console=[('/api/units', 'status of 400')])
    def test_2_a_refused_value_is_shown_and_changes_nothing(self):
        d = self.driver
        self.open('#/site', '#units-table')
        before = self.rows('units-table')
        self.assertEqual(len(before), 2)
        # What the server says to a unit without a code (the page sends a blank code as none).
        status, expected = self.api('POST', '/api/units', {'type': 'deposit', 'description': 'no code'})
        self.assertEqual(status, 400)
        expected = expected['error']
        self.assertEqual(expected.get('field'), 'code')

        form = self.form('unit-form')
        self.fill(form, {'code': '   ', 'description': 'no code'})  # blank: passes `required`, refused by the server
        d.find_element(By.ID, 'add-unit').click()
        msg = self.wait_message(lambda m, k: k == 'error' and m, 20, 'an error in #message for a blank code')
        self.assertEqual(msg, expected['message'], "#message shows the server's message")
        code = form.find_element(By.NAME, 'code')
        self.assertEqual(code.get_attribute('aria-invalid'), 'true')
        self.assertEqual(self.js('return document.activeElement.name;'), 'code', 'the code input has the focus')
        time.sleep(0.5)  # a late reload would show here
        self.assertEqual(self.rows('units-table'), before, 'the units table is unchanged')
        self.assertEqual(len(self.api('GET', '/api/units')[1]), 2)
        # Typing into it clears the mark.
        code.send_keys('1')
        self.assertIsNone(code.get_attribute('aria-invalid'))

    @step()
    def test_3_layer_photos_uploaded_and_resumed(self):
        d = self.driver
        photos = sorted(glob.glob(os.path.join(self.data, 'photos', 'L1', '*.jpg')))
        self.assertEqual(len(photos), 12)
        names = [os.path.basename(p) for p in photos]
        self.open('#/layer/L1', '#layer-summary dl')
        self.assertEqual(d.find_element(By.ID, 'layer-name').text, 'L1')
        self.assertEqual(d.find_element(By.ID, 'layer-unit').text, '101')
        self.assertEqual(d.find_element(By.ID, 'photo-count').text, '0 photos')
        self.assertEqual(d.find_element(By.ID, 'verdict').get_attribute('data-ready'), 'unknown')

        def upload(expected_state, expected_message):
            chooser = d.find_element(By.ID, 'photo-files')
            chooser.clear()
            chooser.send_keys('\n'.join(photos))
            self.assertEqual(self.js("return [...document.getElementById('photo-files').files].map((f) => f.name);"),
                             names)
            t = time.monotonic()
            d.find_element(By.ID, 'upload').click()

            def settled(d):
                rows = d.execute_script("""return [...document.querySelectorAll('#uploads li')].map((li) =>
                    [li.dataset.name, li.dataset.state, li.querySelector('.upload-status').textContent]);""")
                failed = [r for r in rows if r[1] == 'failed']
                if failed:
                    self.fail(f'uploads failed: {failed}')
                done = len(rows) == 12 and all(r[1] == expected_state for r in rows)
                busy = d.find_element(By.ID, 'upload').get_attribute('disabled') is not None
                return rows if done and not busy else None

            rows = self.wait(settled, 120, f'every photo of #uploads {expected_state}')
            print(f'upload ({expected_state}): {time.monotonic() - t:.1f} s', file=sys.stderr)
            self.assertEqual(sorted(r[0] for r in rows), names)
            self.assertEqual({r[2] for r in rows}, {'stored' if expected_state == 'stored' else 'already present'})
            self.wait_message(lambda m, k: m == expected_message, 10, f'#message: {expected_message}')
            # The list of the layer's photos, once reloaded: noted, so that the second
            # upload is still tried when it is wrong.
            try:
                WebDriverWait(d, 10).until(lambda d: d.find_element(By.ID, 'photo-count').text == '12 photos')
            except TimeoutException:
                problems.append(f'after the upload ({expected_state}): #photo-count shows '
                                f'{d.find_element(By.ID, "photo-count").text!r}, not "12 photos"')
            shown = sorted(li.get_attribute('data-name') for li in d.find_elements(By.CSS_SELECTOR, '#photo-list li'))
            if shown != names:
                problems.append(f'after the upload ({expected_state}): #photo-list names {shown}, not the 12 photos')

        problems = []
        upload('stored', '12 stored, 0 already present, 0 failed.')
        # The same files again (an interrupted upload resumed): nothing new is stored.
        upload('present', '0 stored, 12 already present, 0 failed.')
        self.assertEqual(self.api('GET', '/api/site')[1]['photos'], 12, 'the server holds 12 photos')
        self.assertFalse(problems, '\n'.join(problems))

    @step()
    def test_4_markers_imported_from_the_command_line(self):
        with open(os.path.join(self.data, 'gcp_list.txt')) as f:
            lines = f.read().splitlines()
        kept = [lines[0]] + [l for l in lines[1:] if l.split() and l.split()[5].startswith('L1_')]
        self.assertGreater(len(kept), 1, 'gcp_list.txt has observations in L1 photos')
        gcp = os.path.join(SCRATCH, 'gcp_L1.txt')
        with open(gcp, 'w') as f:
            f.write('\n'.join(kept) + '\n')
        # The server holds no lock while idle: a command in a terminal may write.
        run_strata('-q', 'import', 'markers', self.site, gcp, '--format', 'odm')
        run_strata('-q', 'import', 'markers', self.site, os.path.join(self.data, 'markers.csv'))

        with open(os.path.join(self.data, 'markers.csv')) as f:
            surveyed = {r['name'] for r in csv.DictReader(f)}
        self.open('#/site', '#markers-table')
        shown = {r[0] for r in self.rows('markers-table')}
        self.assertEqual(shown, surveyed, 'the site page shows the markers imported')

    @step()
    def test_5_processing_followed_live_then_the_verdict(self):
        d = self.driver
        self.open('#/layer/L1', '#layer-summary dl')
        self.assertEqual(d.find_element(By.ID, 'job-state').text, 'no job')
        d.find_element(By.ID, 'process').click()
        samples = []  # (t, state, stage, has value, value, max)
        t0 = time.monotonic()
        read = """const p = document.getElementById('job-progress');
                  return [document.getElementById('job-state').textContent, document.getElementById('job-stage').textContent,
                          p.hasAttribute('value'), p.value, p.max];"""
        while True:
            state, stage, determinate, value, maximum = self.js(read)
            samples.append((time.monotonic() - t0, state, stage, determinate, value, maximum))
            if state in ('done', 'failed', 'cancelled'):
                break
            if time.monotonic() - t0 > 600:
                self.fail(f'processing not finished after 600 s: job {state}, stage {stage}')
            time.sleep(0.2)
        print(f'processing: {time.monotonic() - t0:.1f} s, {len(samples)} samples', file=sys.stderr)
        self.assertEqual(state, 'done', f'the job ended {state}: {d.find_element(By.ID, "job-message").text!r}; '
                                        f'#message {self.message()!r}')

        running = [s for s in samples if s[1] in ('queued', 'running')]
        stages = []
        for s in running:
            if s[2] and s[2] != 'starting' and s[2] not in stages:
                stages.append(s[2])
        print(f'stages shown: {stages}', file=sys.stderr)
        self.assertGreaterEqual(len(stages), 3, f'at least 3 stages shown while running: {stages}')
        moved = []
        for a, b in zip(running, running[1:]):
            if a[2] == b[2] and a[3] and b[3] and a[5] == b[5] and b[4] > a[4]:
                moved.append((b[2], a[4], b[4], b[5]))
        print(f'progress moves seen: {len(moved)}, e.g. {moved[:5]}', file=sys.stderr)
        self.assertTrue(moved, 'within a stage, the progress bar shown moved forward at least once')
        self.assertEqual(d.find_element(By.ID, 'job-percent').text, '100 %')
        self.assertTrue(d.find_elements(By.CSS_SELECTOR, '#job-log li'), 'the log shows the job\'s lines')
        self.assertEqual(d.find_element(By.ID, 'process').get_attribute('disabled'), None)
        self.assertEqual(d.find_element(By.ID, 'cancel').get_attribute('disabled'), 'true')

        ready = self.wait(lambda d: d.find_element(By.ID, 'verdict').get_attribute('data-ready') in ('true', 'false')
                          and d.find_element(By.ID, 'verdict').get_attribute('data-ready'), 60,
                          '#verdict data-ready true or false')
        headline = d.find_element(By.ID, 'verdict-headline').text.strip()
        self.assertTrue(headline, '#verdict-headline has text')
        self.assertEqual(headline, 'Ready to dig' if ready == 'true' else 'Not ready to dig')
        findings = [(li.get_attribute('data-severity'), li.text) for li in d.find_elements(By.CSS_SELECTOR, '#findings li')]
        print(f'verdict: {headline} ({ready}); findings: {findings}', file=sys.stderr)
        flags = {e.get_attribute('data-state'): e.find_element(By.CSS_SELECTOR, '.tick').get_attribute('data-value')
                 for e in d.find_elements(By.CSS_SELECTOR, '#layer-state .flag-item')}
        self.assertEqual(flags, {'aligned': 'yes', 'dense': 'yes', 'products': 'yes'})

        href = d.find_element(By.ID, 'report-link').get_attribute('href')
        self.assertTrue(href.endswith('/api/layers/L1/report'), href)
        with urllib.request.urlopen(href, timeout=60) as r:
            self.assertEqual(r.status, 200)
            csp = r.headers.get('Content-Security-Policy', '')
            report = r.read().decode('utf-8', errors='replace')
        self.assertIn('<html', report.lower())
        self.assertIn('sandbox', csp)
        # The report itself, under the verdict, in a frame without scripts: its coverage map shown.
        frame = d.find_element(By.ID, 'report-frame')
        self.js("arguments[0].scrollIntoView();", frame)
        d.switch_to.frame(frame)
        try:
            self.wait(lambda d: 'field report' in d.find_element(By.TAG_NAME, 'body').text, 60,
                      'the field report shown in the layer page')
            drawings = self.js("return [...document.querySelectorAll('svg')].filter((s) => s.getBoundingClientRect().width > 0).length;")
        finally:
            d.switch_to.default_content()
        self.assertGreater(drawings, 0, 'the report in the frame shows its drawings (coverage map, plan)')
        self.js("for (const x of document.querySelectorAll('details')) x.open = true;")
        self.screenshot('layer')

    @step()
    def test_6_finds_recorded_at_a_surveyed_point(self):
        d = self.driver
        with open(os.path.join(self.data, 'markers.csv'), newline='') as f:
            reader = csv.reader(f)
            header = [h.strip().lower() for h in next(reader)]
            first = next(reader)
        col = {k: header.index(k) for k in ('e', 'n', 'z')}
        e, n, z = (first[col[k]].strip() for k in ('e', 'n', 'z'))
        self.open('#/finds', '#finds-table')
        self.assertEqual(self.rows('finds-table'), [])
        form = self.form('find-form')
        self.wait(lambda d: d.execute_script(
            "return [...document.querySelectorAll('#find-form select[name=unit] option')].some((o) => o.value === '101');"),
            10, 'the find form offers unit 101')
        self.fill(form, {'id': 'F1', 'e': e, 'n': n, 'z': z, 'unit': '101', 'type': 'pottery',
                         'description': 'rim sherd'})
        d.find_element(By.ID, 'add-find').click()
        row = self.wait_row('finds-table', 'F1')
        self.wait_message(lambda m, k: m == 'Find F1 recorded.' and k == 'ok', 10, 'message "Find F1 recorded."')
        self.assertEqual(row[1:4], [f'{float(e):.3f}', f'{float(n):.3f}', f'{float(z):.3f}'])
        self.assertEqual(row[4:7], ['101', 'pottery', 'rim sherd'])
        self.assertEqual(Select(form.find_element(By.NAME, 'unit')).first_selected_option.get_attribute('value'), '101',
                         'the unit is kept for the next find')
        self.screenshot('finds')

    @step()
    def test_7_phone_width(self):
        d = self.driver
        size = d.get_window_size()
        try:
            d.set_window_size(390, 844)
            self.open('#/site', '#units-table')
            time.sleep(0.3)  # the matrix image may still change the layout
            inner, scroll = self.js('return [window.innerWidth, document.documentElement.scrollWidth];')
            print(f'phone: innerWidth {inner}, scrollWidth {scroll}', file=sys.stderr)
            self.assertLessEqual(inner, 420, 'the window is phone-wide')
            self.assertLessEqual(scroll, inner + 1, 'the page does not scroll sideways')
            heights = self.js("""return Object.fromEntries([...document.querySelectorAll('#page button')]
                                   .map((b) => [b.id, b.getBoundingClientRect().height]));""")
            print(f'phone: button heights {heights}', file=sys.stderr)
            self.assertGreaterEqual(heights['add-unit'], 44, '#add-unit is at least 44 px high')
            small = self.js("""return [...document.querySelectorAll('#page input, #page select, #page button')]
                .filter((c) => c.getBoundingClientRect().height < 44)
                .map((c) => `${c.tagName.toLowerCase()}[name=${c.name}] ${c.getBoundingClientRect().height}`);""")
            if small:
                print(f'phone: controls under 44 px: {small}', file=sys.stderr)
            self.screenshot('phone')
        finally:
            d.set_window_size(size['width'], size['height'])

    # ---- the marker workspace and the 3D page --------------------------------------
    def truth_clicks(self):
        """The generator's gcp_list.txt for L1: marker -> {photo: (x, y)} (true pixels)."""
        out = {}
        with open(os.path.join(self.data, 'gcp_list.txt')) as f:
            next(f)
            for line in f:
                parts = line.split()
                if len(parts) >= 7 and parts[5].startswith('L1_'):
                    out.setdefault(parts[6], {})[parts[5]] = (float(parts[3]), float(parts[4]))
        return out

    def strip_status(self, photo):
        return self.js("const t = document.querySelector(`#photo-strip [data-photo=\"${arguments[0]}\"]`);"
                       "return t ? t.dataset.status : null;", photo)

    def stored(self, marker, photo):
        status, body = self.api('GET', f'/api/layers/L1/markers/{marker}')
        self.assertEqual(status, 200, body)
        return next(p for p in body['photos'] if p['name'] == photo)

    def choose_photo(self, photo):
        self.driver.find_element(By.CSS_SELECTOR, f'#photo-strip [data-photo="{photo}"]').click()
        self.wait(lambda d: d.execute_script(
            "return window.strataMarkers && window.strataMarkers.view().photo === arguments[0] && "
            "document.getElementById('photo-view').dataset.state === 'ready';", photo), 30, f'photo {photo} shown')

    @step(allowed_console=[('/api/layers/L1/guide', 'status of 4')])
    def test_9_markers_clicked_predicted_confirmed_georeferenced(self):
        d = self.driver
        truth = self.truth_clicks()
        marker = next(m for m, seen in sorted(truth.items()) if len(seen) >= 3)
        photos = sorted(truth[marker])
        cleared, clicked = photos[len(photos) // 2], photos[0]
        self.open('#/markers/L1', f'#marker-list [data-marker="{marker}"]')
        d.find_element(By.CSS_SELECTOR, f'#marker-list [data-marker="{marker}"]').click()
        self.wait(lambda d: self.strip_status(cleared) == 'clicked', 20, f'{marker} in {cleared} shown as clicked')
        check_before = d.find_element(By.ID, 'check-rmse').text

        # A click withdrawn with one key, then predicted by the guide, then confirmed with one key.
        self.choose_photo(cleared)
        d.find_element(By.TAG_NAME, 'body').send_keys('u')
        self.wait(lambda d: self.strip_status(cleared) == 'none', 20, f'{marker} in {cleared} cleared, still in the strip')
        button = d.find_element(By.ID, 'guide')
        self.js("arguments[0].scrollIntoView({block: 'center'});", button)
        button.click()
        self.wait_message(lambda m, k: 'predicted position' in m, 60, 'the guide says how many positions it predicted')
        self.wait(lambda d: self.strip_status(cleared) == 'predicted', 20, f'{marker} in {cleared} predicted')
        p = self.stored(marker, cleared)
        tx, ty = truth[marker][cleared]
        off = ((p['observation']['x'] - tx) ** 2 + (p['observation']['y'] - ty) ** 2) ** 0.5
        print(f'markers: {marker} in {cleared} predicted {off:.3f} px from the truth', file=sys.stderr)
        self.assertLess(off, 1.0)
        self.choose_photo(cleared)
        d.find_element(By.TAG_NAME, 'body').send_keys('y')
        self.wait(lambda d: self.strip_status(cleared) == 'confirmed', 20, f'{marker} in {cleared} confirmed')

        # A click on the photo, zoomed in: stored in full-image pixels where the pointer was.
        self.choose_photo(clicked)
        d.find_element(By.TAG_NAME, 'body').send_keys('f')  # centred on the marker, close up
        time.sleep(0.5)
        tx, ty = truth[marker][clicked]
        self.js("const v = document.getElementById('photo-canvas'); v.scrollIntoView({block: 'center'});")
        centre = self.js("""const c = window.strataMarkers.imageToClient(arguments[0], arguments[1]);
            const r = document.getElementById('photo-canvas').getBoundingClientRect();
            return [c.x - (r.left + r.width / 2), c.y - (r.top + r.height / 2), window.strataMarkers.view().scale];""",
                         tx, ty)
        dx, dy, scale = centre
        self.assertGreater(scale, 1.0, 'zoomed in past one screen pixel per photo pixel')
        ActionChains(d).move_to_element_with_offset(d.find_element(By.ID, 'photo-canvas'), round(dx), round(dy)) \
            .click().perform()
        self.wait(lambda d: d.find_element(By.ID, 'click-readout').get_attribute('data-x'), 20, 'the click is stored')
        readout = d.find_element(By.ID, 'click-readout')
        shown = (float(readout.get_attribute('data-x')), float(readout.get_attribute('data-y')))
        p = self.stored(marker, clicked)
        self.assertEqual(p['status'], 'clicked')
        self.assertAlmostEqual(p['observation']['x'], shown[0], places=6)
        self.assertAlmostEqual(p['observation']['y'], shown[1], places=6)
        off = ((shown[0] - tx) ** 2 + (shown[1] - ty) ** 2) ** 0.5
        print(f'markers: clicked at {shown[0]:.3f}, {shown[1]:.3f} ({off:.3f} px from the true pixel; '
              f'{scale:.2f} screen px per photo px)', file=sys.stderr)
        self.assertLess(off, 1.0 / scale + 0.5)  # the pointer lands on a whole screen pixel

        # Georeference again: the check RMSE shown changes, the previous one beside it.
        button = d.find_element(By.ID, 'georeference')
        self.js("arguments[0].scrollIntoView({block: 'center'});", button)  # not under the sticky message bar
        button.click()
        self.wait(lambda d: d.find_element(By.ID, 'georef-progress').get_attribute('data-state') == 'done', 300,
                  'the georeference job is done')
        self.wait(lambda d: d.find_elements(By.CSS_SELECTOR, '#check-rmse .rmse-was'), 30,
                  'the check RMSE shows the value before')
        print(f'markers: check RMSE before {check_before!r}, after {d.find_element(By.ID, "check-rmse").text!r}',
              file=sys.stderr)
        self.screenshot('markers', full=False)

    @step()
    def test_8_the_site_in_3d(self):
        # Before the marker workspace georeferences again (which makes the dense surface stale).
        d = self.driver
        self.open('#/3d', '#view3d-frame')
        d.switch_to.frame(d.find_element(By.ID, 'view3d-frame'))
        try:
            self.wait(lambda d: d.find_element(By.ID, 'status').text.startswith('loaded'), 120,
                      'the viewer in the 3D page says it loaded the model')
            status = d.find_element(By.ID, 'status').text
            layers = [e.text for e in d.find_elements(By.CSS_SELECTOR, '#layers label')]
        finally:
            d.switch_to.default_content()
        print(f'3d: {status}; layers {layers}', file=sys.stderr)
        self.assertTrue(any('L1' in l for l in layers), layers)
        self.screenshot('view3d', full=False)

    @step(allowed_console=[('/api/sections', 'status of 4')])
    def test_8_map_tiles_coordinates_and_section(self):
        d = self.driver
        status, site_map = self.api('GET', '/api/map')
        self.assertEqual(status, 200)
        self.assertTrue(site_map['layers'], 'a processed layer is on the map')
        ortho = site_map['layers'][-1]['ortho']
        self.open('#/map', '#map.leaflet-container')
        # A tile of the orthophoto, loaded, 256 px, with pixels of the layer in it.
        tile_js = """
            const tiles = [...document.querySelectorAll('#map img.leaflet-tile.leaflet-tile-loaded')]
                .filter((i) => i.complete && i.naturalWidth === 256 && i.src.includes('/tiles/ortho/'));
            let best = 0;
            for (const img of tiles) {
              const c = document.createElement('canvas');
              c.width = c.height = 256;
              const g = c.getContext('2d');
              g.drawImage(img, 0, 0);
              const a = g.getImageData(0, 0, 256, 256).data;
              let opaque = 0;
              for (let i = 3; i < a.length; i += 4) if (a[i] > 0) opaque++;
              best = Math.max(best, opaque);
            }
            return [tiles.length, best];"""
        loaded, opaque = self.wait(lambda d: (lambda r: r if r[0] > 0 and r[1] > 0 else None)(self.js(tile_js)), 30,
                                   'an orthophoto tile loaded with pixels of the layer')
        print(f'map: {loaded} ortho tiles loaded, the fullest with {opaque} opaque pixels', file=sys.stderr)
        markers = self.js("return document.querySelectorAll('#map path.leaflet-interactive').length;")
        self.assertGreaterEqual(markers, len(site_map['markers']), 'a circle per marker (and the footprint)')
        # The pointer's coordinates in the site CRS, inside the orthophoto at its centre.
        m = d.find_element(By.ID, 'map')
        ActionChains(d).move_to_element_with_offset(m, 0, 0).move_by_offset(3, 2).perform()
        text = self.wait(lambda d: (lambda t: t if t.startswith('E ') and 'N ' in t and '—' not in t else None)(
            d.find_element(By.ID, 'map-coords').text), 10, '#map-coords shows E, N')
        found = re.fullmatch(r'E (\d+\.\d{3}), N (\d+\.\d{3})', text)
        self.assertIsNotNone(found, text)
        e, n = float(found.group(1)), float(found.group(2))
        margin = 0.5 * (ortho['e_max'] - ortho['e_min'])
        self.assertTrue(ortho['e_min'] - margin < e < ortho['e_max'] + margin and
                        ortho['n_min'] - margin < n < ortho['n_max'] + margin, f'{text} is on the site')
        self.screenshot('map')
        # The section tool: two taps on the map.
        d.find_element(By.ID, 'section-tool').click()
        self.assertEqual(d.find_element(By.ID, 'section-tool').get_attribute('aria-pressed'), 'true')
        width = m.size['width']
        ActionChains(d).move_to_element_with_offset(m, -width // 6, 0).click().perform()
        ActionChains(d).move_to_element_with_offset(m, width // 6, 0).click().perform()
        if len(site_map['layers']) >= 2:
            self.wait(lambda d: d.execute_script(
                "const i = document.querySelector('#section-view img'); return i && i.complete && i.naturalWidth > 0;"),
                120, 'the section drawing shown in #section-view')
            self.assertEqual(d.find_element(By.ID, 'section-download').get_attribute('download'), 'section.svg')
        else:
            # One layer processed: the server's refusal, as the volume code says it.
            msg = self.wait_message(lambda m, k: k == 'error' and 'at least two' in m, 60,
                                    "the refusal of a section with one layer's surface")
            print(f'map: section refused: {msg!r}', file=sys.stderr)
            self.assertEqual(d.find_elements(By.CSS_SELECTOR, '#section-view img'), [], 'no drawing is shown')
        self.screenshot('map_section')
        size = d.get_window_size()
        try:
            d.set_window_size(390, 844)
            self.open('#/map', '#map.leaflet-container')
            self.wait(lambda d: self.js(tile_js)[0] > 0, 30, 'a tile loaded on the phone')
            inner, scroll = self.js('return [window.innerWidth, document.documentElement.scrollWidth];')
            box = self.js("const r = document.getElementById('map').getBoundingClientRect(); return [r.width, r.height];")
            print(f'map on the phone: innerWidth {inner}, map {box}', file=sys.stderr)
            self.assertLessEqual(scroll, inner + 1, 'the map page does not scroll sideways')
            self.assertGreater(box[0], 0.9 * inner - 20, 'the map fills the width')
            self.assertGreater(box[1], 0.5 * self.js('return window.innerHeight;'), 'the map is most of the screen high')
            self.screenshot('map_phone', full=False)
        finally:
            d.set_window_size(size['width'], size['height'])


def main():
    global STRATA, SCRATCH
    args, rest = parse_args(sys.argv[1:])
    STRATA = os.path.abspath(args.strata)
    SCRATCH = os.path.abspath(args.scratch)
    if not os.access(STRATA, os.X_OK):
        sys.exit(f'{STRATA}: not an executable')
    unittest.main(argv=[sys.argv[0], *rest], verbosity=2)


if __name__ == '__main__':
    main()
