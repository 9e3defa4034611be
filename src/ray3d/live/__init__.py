"""Live: a camera stream in, people on the floor plan, events and a web page out, as the frames arrive
(``ray3d live``; ``runner.follow``). The frame source (``source``), who is where causally (``people``), the webhook
(``outputs``), the page (``server``) and the loop that joins them (``runner``); the site's events come from
``ray3d.site.SiteMonitor``, several cameras' people are joined by ``ray3d.fusion.live``, and a live job is
assembled and finished by ``ray3d.jobs.live``."""
