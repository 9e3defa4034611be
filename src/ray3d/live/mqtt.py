"""Live events on MQTT, the bus home and building automation listens to (``MqttPublisher``, paho-mqtt): each event
as JSON on ``<prefix>/event`` (QoS 1, in order), each zone's occupancy and each line's and zone's running counts
retained on ``<prefix>/zone/<zone>/occupancy`` ... (a subscriber joining later reads the state at once), the
service's availability on ``<prefix>/status`` (``online``; the broker says ``offline`` for it if the process
dies), and every zone and line announced to Home Assistant's MQTT discovery (``homeassistant/sensor/...``),
so that they appear there as sensors without configuration.

A broker that is down is retried in the background by the client (1 s doubling to 30 s) and never slows the
stream: at most ``queue_size`` messages wait (paho's own bounded queue); beyond, they are counted as dropped and
said once."""

from __future__ import annotations

import json
import re
import sys
import threading
from collections.abc import Callable
from urllib.parse import urlsplit

from ray3d.errors import InputError
from ray3d.site.places import Site

DISCOVERY_PREFIX = "homeassistant"
DEFAULT_PORT = 1883


def _slug(name: str) -> str:
    """A name as a topic level or a discovery id (letters, digits, _ and -)."""
    return re.sub(r"[^A-Za-z0-9_-]+", "_", str(name)).strip("_") or "unnamed"


def parse_mqtt_url(url: str) -> tuple[str, int, str]:
    """``mqtt://host[:port]/prefix`` -> (host, port, prefix); refused naming the problem."""
    parts = urlsplit(str(url))
    if parts.scheme != "mqtt" or not parts.hostname:
        raise InputError(f"mqtt: {url}: give mqtt://HOST[:PORT]/PREFIX", ("mqtt",))
    try:
        port = parts.port or DEFAULT_PORT
    except ValueError:
        raise InputError(f"mqtt: {url}: the port is not a number from 1 to 65535", ("mqtt",)) from None
    prefix = parts.path.strip("/") or "ray3d"
    if any(c in prefix for c in "+#") or "//" in prefix:
        raise InputError(f"mqtt: {url}: the prefix may not hold + # or empty levels", ("mqtt",))
    return parts.hostname, port, prefix


def sensors(site: Site, prefix: str) -> list[tuple[str, dict]]:
    """The site's zones and lines as Home Assistant MQTT sensors: (discovery topic, config payload) each. A zone
    gives its occupancy (people now) and its entries; a line its crossings each way."""
    node = _slug(prefix)
    device = {"identifiers": [f"ray3d_{node}"], "name": f"ray3d {prefix}", "manufacturer": "ray3d",
              "model": "ray3d live"}
    common = {"availability_topic": f"{prefix}/status", "payload_available": "online",
              "payload_not_available": "offline", "device": device}
    found = []
    for zone in site.zones:
        for what, unit, state_class, icon in (("occupancy", "people", "measurement", "mdi:account-group"),
                                              ("entries", "entries", "total_increasing", "mdi:login")):
            object_id = f"{_slug(zone.name)}_{what}"
            found.append((f"{DISCOVERY_PREFIX}/sensor/{node}/{object_id}/config",
                          {"name": f"{zone.name} {what}", "unique_id": f"ray3d_{node}_{object_id}",
                           "state_topic": f"{prefix}/zone/{_slug(zone.name)}/{what}",
                           "unit_of_measurement": unit, "state_class": state_class, "icon": icon, **common}))
    for line in site.lines:
        for direction in ("forward", "back"):
            object_id = f"{_slug(line.name)}_{direction}"
            found.append((f"{DISCOVERY_PREFIX}/sensor/{node}/{object_id}/config",
                          {"name": f"{line.name} crossings {direction}", "unique_id": f"ray3d_{node}_{object_id}",
                           "state_topic": f"{prefix}/line/{_slug(line.name)}/{direction}",
                           "unit_of_measurement": "crossings", "state_class": "total_increasing",
                           "icon": "mdi:transit-transfer", **common}))
    return found


class MqttPublisher:
    """Publishes a live run's events and its site's state to the broker at ``url`` (``mqtt://host:port/prefix``).
    ``published`` counts the events handed to the client, ``dropped`` those its full queue refused."""

    def __init__(self, url: str, site: Site, queue_size: int = 1000, client_id: str | None = None,
                 report: Callable[[str], None] = lambda line: print(line, file=sys.stderr)):
        try:
            import paho.mqtt.client as mqtt
        except ImportError:
            raise InputError("mqtt: needs paho-mqtt (pip install 'ray3d[live]')", ("mqtt",)) from None
        self.host, self.port, self.prefix = parse_mqtt_url(url)
        self.site, self.report = site, report
        self.published = self.dropped = 0
        self._state: dict[str, str] = {}  # retained topic -> the value last published
        self._reported = False
        self._lock = threading.Lock()
        self._codes = (mqtt.MQTT_ERR_SUCCESS, mqtt.MQTT_ERR_NO_CONN)  # sent, or queued until the broker is back
        self._client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=client_id or "",
                                   clean_session=True)
        self._client.max_queued_messages_set(queue_size)
        self._client.reconnect_delay_set(1, 30)
        self._client.will_set(f"{self.prefix}/status", "offline", qos=1, retain=True)
        self._client.on_connect = self._connected
        self._client.connect_async(self.host, self.port, keepalive=30)
        self._client.loop_start()

    def _connected(self, client, userdata, flags, reason, properties=None) -> None:
        """On each (re)connection: online, the sensors announced and the state retained again."""
        if getattr(reason, "is_failure", False):
            return
        client.publish(f"{self.prefix}/status", "online", qos=1, retain=True)
        for topic, payload in sensors(self.site, self.prefix):
            client.publish(topic, json.dumps(payload), qos=1, retain=True)

    def _send(self, topic: str, payload: str, retain: bool) -> bool:
        info = self._client.publish(topic, payload, qos=1, retain=retain)
        if info.rc in self._codes:
            return True
        self.dropped += 1
        if not self._reported:
            self._reported = True
            self.report(f"mqtt {self.host}:{self.port}: the broker is not taking messages; those beyond the queue "
                        "are dropped (events stay in events.jsonl and the store)")
        return False

    def publish(self, events: list[dict], monitor) -> None:
        """The events just found (each on ``<prefix>/event``), then the state they changed, retained: each zone's
        occupancy and entries and each line's crossings (``monitor``: the run's ``SiteMonitor``)."""
        if not events:
            return
        with self._lock:
            for event in events:
                self.published += self._send(f"{self.prefix}/event", json.dumps(event), retain=False)
            state = {**{f"{self.prefix}/zone/{_slug(z)}/occupancy": str(len(people))
                        for z, people in monitor.occupants.items()},
                     **{f"{self.prefix}/zone/{_slug(z.name)}/entries": str(monitor.counts[z.name]["entered"])
                        for z in self.site.zones},
                     **{f"{self.prefix}/line/{_slug(l.name)}/{d}": str(monitor.counts[l.name][d])
                        for l in self.site.lines for d in ("forward", "back")}}
            for topic, value in state.items():
                if self._state.get(topic) != value:
                    self._state[topic] = value
                    self._send(topic, value, retain=True)

    def close(self, wait_s: float = 3.0) -> None:
        """What waits sent for up to ``wait_s`` seconds, ``offline`` said, the connection closed."""
        import time

        deadline = time.monotonic() + wait_s
        if self._client.is_connected():
            info = self._client.publish(f"{self.prefix}/status", "offline", qos=1, retain=True)
            try:
                info.wait_for_publish(timeout=max(0.0, deadline - time.monotonic()))
            except (RuntimeError, ValueError):
                pass
        self._client.disconnect()
        self._client.loop_stop()
