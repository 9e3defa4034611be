"""A site: its places (``places``: zones, counting lines, a floor picture), the events people make on them on
both clocks (``events``: one causal engine, replayed over a finished world), what they add up to (``analytics``),
falls (``falls``), and the report written from them (``report``)."""

from ray3d.site.events import EVENT_KINDS, Event, EventKind, SiteMonitor, site_events
from ray3d.site.places import CountingLine, FloorPlan, Site, Zone, in_zones, line_crossings

__all__ = ["EVENT_KINDS", "CountingLine", "Event", "EventKind", "FloorPlan", "Site", "SiteMonitor", "Zone",
           "in_zones", "line_crossings", "site_events"]
