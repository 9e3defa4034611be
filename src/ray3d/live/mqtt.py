"""Live events on MQTT, the bus home and building automation listens to (``MqttPublisher``, paho-mqtt): each event
as JSON on ``<prefix>/event`` (QoS 1, in order), each zone's occupancy and each line's and zone's running counts
retained on ``<prefix>/zone/<zone>/occupancy`` ... (a subscriber joining later reads the state at once; the counts
go on from the store's, so a restart does not set them back to 0), the crossings, visits, limits and falls as
Home Assistant events on ``<prefix>/line/<line>/crossing``, ``<prefix>/zone/<zone>/event`` and ``<prefix>/fall``,
the service's availability on ``<prefix>/status`` (``online``; the broker says ``offline`` for it if the process
dies), and every zone and line announced to Home Assistant's MQTT discovery (``homeassistant/sensor/...`` and
``homeassistant/event/...``), so that they appear there as sensors and as events to automate on, without
configuration; and whether the run keeps up with its streams (``<prefix>/health/state``, ``.../dropped_percent``,
``<prefix>/health``: ``health_sensors``). A zone's or line's name becomes a topic level by ``topic_name``
(``line A (middle)`` -> ``line_A_middle``).

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

from ray3d.console import said_once
from ray3d.errors import InputError
from ray3d.site.events import DWELL_ABOVE_LIMIT, FALL, LINE_CROSSED, OCCUPANCY_ABOVE_LIMIT, ZONE_ENTERED, ZONE_LEFT
from ray3d.site.places import Site

DISCOVERY_PREFIX = "homeassistant"
DEFAULT_PORT = 1883


def topic_name(name: str) -> str:
    """A zone's or line's name as a topic level or a discovery id: each run of characters other than ASCII letters,
    digits, _ and - becomes one _, and _ at either end is dropped (``line A (middle)`` -> ``line_A_middle``;
    nothing left: ``unnamed``)."""
    return re.sub(r"[^A-Za-z0-9_-]+", "_", str(name)).strip("_") or "unnamed"



def _one_topic_each(site: Site, prefix: str) -> None:
    """Refused: two zones (or two lines) whose names become one topic, their counts would be mixed."""
    for kind, places in (("zone", site.zones), ("line", site.lines)):
        seen: dict[str, str] = {}
        for place in places:
            name = topic_name(place.name)
            if name in seen:
                raise InputError(f"mqtt: {kind}s {seen[name]!r} and {place.name!r} would share the topic "
                                 f"{prefix}/{kind}/{name}; rename one", ("site",))
            seen[name] = place.name


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


def _common(prefix: str) -> dict:
    """What every announced entity shares: the service's availability and its one device."""
    device = {"identifiers": [f"ray3d_{topic_name(prefix)}"], "name": f"ray3d {prefix}", "manufacturer": "ray3d",
              "model": "ray3d live"}
    return {"availability_topic": f"{prefix}/status", "payload_available": "online",
            "payload_not_available": "offline", "device": device}


def sensors(site: Site, prefix: str) -> list[tuple[str, dict]]:
    """The site's zones and lines as Home Assistant MQTT sensors: (discovery topic, config payload) each. A zone
    gives its occupancy (people now), its entries and its exits; a line its crossings each way."""
    node, common = topic_name(prefix), _common(prefix)

    def sensor(place: str, kind: str, what: str, name: str, unit: str, state_class: str, icon: str):
        object_id = f"{topic_name(place)}_{what}"
        return (f"{DISCOVERY_PREFIX}/sensor/{node}/{object_id}/config",
                {"name": name, "unique_id": f"ray3d_{node}_{object_id}",
                 "state_topic": f"{prefix}/{kind}/{topic_name(place)}/{what}", "unit_of_measurement": unit,
                 "state_class": state_class, "icon": icon, **common})

    found = [sensor(zone.name, "zone", what, f"{zone.name} {what}", unit, state_class, icon)
             for zone in site.zones
             for what, unit, state_class, icon in (("occupancy", "people", "measurement", "mdi:account-group"),
                                                   ("entries", "entries", "total_increasing", "mdi:login"),
                                                   ("exits", "exits", "total_increasing", "mdi:logout"))]
    return found + [sensor(line.name, "line", direction, f"{line.name} crossings {direction}", "crossings",
                           "total_increasing", "mdi:transit-transfer")
                    for line in site.lines for direction in ("forward", "back")]


# A zone's events -> their ``event_type`` on the zone's Home Assistant event entity.
ZONE_EVENT_TYPES = {ZONE_ENTERED.name: "entered", ZONE_LEFT.name: "left",
                    OCCUPANCY_ABOVE_LIMIT.name: "occupancy_above_limit", DWELL_ABOVE_LIMIT.name: "dwell_above_limit"}


def home_assistant_event(event: dict) -> tuple[str, str] | None:
    """Where ``event`` goes as a Home Assistant event (its topic under the prefix) and its ``event_type``; None for
    track starts and ends (on ``<prefix>/event`` only)."""
    kind = event["event"]
    if kind == LINE_CROSSED.name:
        return f"line/{topic_name(event['line'])}/crossing", event["direction"]
    if kind in ZONE_EVENT_TYPES:
        return f"zone/{topic_name(event['zone'])}/event", ZONE_EVENT_TYPES[kind]
    return (FALL.name, FALL.name) if kind == FALL.name else None  # the topic PREFIX/fall, its one type


def event_entities(site: Site, prefix: str) -> list[tuple[str, dict]]:
    """The site's happenings as Home Assistant MQTT event entities (what an automation triggers on): (discovery
    topic, config payload) each. A line's crossings (``forward``, ``back``), a zone's visits and limits
    (``entered``, ``left``, ``occupancy_above_limit``, ``dwell_above_limit``) and the site's falls (``fall``); each
    published as the event's JSON with its ``event_type``."""
    node, common = topic_name(prefix), _common(prefix)
    places = [(f"{topic_name(line.name)}_crossing", f"{line.name} crossing",
               f"line/{topic_name(line.name)}/crossing", ["forward", "back"], "mdi:transit-transfer")
              for line in site.lines]
    places += [(f"{topic_name(zone.name)}_event", zone.name, f"zone/{topic_name(zone.name)}/event",
                list(ZONE_EVENT_TYPES.values()), "mdi:map-marker-radius") for zone in site.zones]
    places.append((FALL.name, FALL.name, FALL.name, [FALL.name], "mdi:human-handsdown"))  # PREFIX/fall
    return [(f"{DISCOVERY_PREFIX}/event/{node}/{object_id}/config",
             {"name": name, "unique_id": f"ray3d_{node}_{object_id}", "state_topic": f"{prefix}/{topic}",
              "event_types": types, "icon": icon, **common})
            for object_id, name, topic, types, icon in places]


KEEPING_UP, FALLING_BEHIND = "keeping up", "falling behind"


def health_sensors(prefix: str) -> list[tuple[str, dict]]:
    """The service's health as Home Assistant MQTT sensors: whether it keeps up with its streams
    (``<prefix>/health/state``: ``keeping up`` or ``falling behind``, its details as attributes from
    ``<prefix>/health``) and the share of frames dropped over the last 10 s, of the camera dropping most
    (``<prefix>/health/dropped_percent``). While it falls behind, counts are uncertain."""
    node, common = topic_name(prefix), _common(prefix)
    return [(f"{DISCOVERY_PREFIX}/sensor/{node}/health/config",
             {"name": "keeping up with the cameras", "unique_id": f"ray3d_{node}_health",
              "state_topic": f"{prefix}/health/state", "device_class": "enum", "options": [KEEPING_UP, FALLING_BEHIND],
              "json_attributes_topic": f"{prefix}/health", "entity_category": "diagnostic",
              "icon": "mdi:speedometer", **common}),
            (f"{DISCOVERY_PREFIX}/sensor/{node}/dropped_percent/config",
             {"name": "frames dropped", "unique_id": f"ray3d_{node}_dropped_percent",
              "state_topic": f"{prefix}/health/dropped_percent", "unit_of_measurement": "%",
              "state_class": "measurement", "entity_category": "diagnostic", "icon": "mdi:speedometer-slow",
              **common})]


def announcements(site: Site, prefix: str) -> list[tuple[str, dict]]:
    """Everything announced to Home Assistant's MQTT discovery: the sensors, the event entities and the
    service's health."""
    return sensors(site, prefix) + event_entities(site, prefix) + health_sensors(prefix)


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
        _one_topic_each(site, self.prefix)
        self.site, self.report_trouble = site, said_once(report)
        self.published = self.dropped = 0
        self._state: dict[str, str] = {}  # retained topic -> the value last published
        self._before: dict[str, dict[str, int]] = {}  # the counts of the runs before this one (the store's)
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
        for topic, payload in announcements(self.site, self.prefix):
            client.publish(topic, json.dumps(payload), qos=1, retain=True)

    def _send(self, topic: str, payload: str, retain: bool) -> bool:
        info = self._client.publish(topic, payload, qos=1, retain=retain)
        if info.rc in self._codes:
            return True
        self.dropped += 1
        self.report_trouble(f"mqtt {self.host}:{self.port}: the broker is not taking messages; those beyond the queue "
                            "are dropped (events stay in events.jsonl and the store)")
        return False

    def begin(self, monitor, counted: dict[str, dict[str, int]] | None = None) -> None:
        """The run's state published at its start, its running counts going on from ``counted`` (the counts of the
        runs before it, ``store.RunRecorder.counted``: a restart does not set them back to 0)."""
        with self._lock:
            self._before = counted or {}
            self._publish_state(monitor)

    def publish(self, events: list[dict], monitor) -> None:
        """The events just found (each on ``<prefix>/event``, and those Home Assistant is told of as events on
        their place's topic, ``home_assistant_event``), then the state they changed, retained: each zone's
        occupancy, entries and exits and each line's crossings (``monitor``: the run's ``SiteMonitor``)."""
        if not events:
            return
        with self._lock:
            for event in events:
                self.published += self._send(f"{self.prefix}/event", json.dumps(event), retain=False)
                if (announced := home_assistant_event(event)) is not None:
                    topic, event_type = announced
                    self._send(f"{self.prefix}/{topic}", json.dumps({"event_type": event_type, **event}), retain=False)
            self._publish_state(monitor)

    def health(self, state: dict) -> None:
        """Whether the run keeps up (``live.health.Keeping.state``), retained, published where it changed: the
        state, the worst camera's share of frames dropped (whole percent) and the details (the latest 10
        stretches)."""
        worst = max(state["dropped_percent"].values(), default=0.0)
        details = json.dumps({**state, "dropped_percent": {k: round(v) for k, v in state["dropped_percent"].items()},
                              "stretches": state["stretches"][-10:]})
        with self._lock:
            for topic, value in ((f"{self.prefix}/health", details),
                                 (f"{self.prefix}/health/state", FALLING_BEHIND if state["falling_behind"]
                                  else KEEPING_UP),
                                 (f"{self.prefix}/health/dropped_percent", f"{worst:.0f}")):
                if self._state.get(topic) != value:
                    self._state[topic] = value
                    self._send(topic, value, retain=True)

    def _publish_state(self, monitor) -> None:
        def count(place: str, what: str) -> str:
            return str(self._before.get(place, {}).get(what, 0) + monitor.counts[place][what])

        state = {**{f"{self.prefix}/zone/{topic_name(z)}/occupancy": str(len(people))
                    for z, people in monitor.occupants.items()},
                 **{f"{self.prefix}/zone/{topic_name(z.name)}/{topic}": count(z.name, what)
                    for z in self.site.zones for topic, what in (("entries", "entered"), ("exits", "left"))},
                 **{f"{self.prefix}/line/{topic_name(line.name)}/{d}": count(line.name, d)
                    for line in self.site.lines for d in ("forward", "back")}}
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
