"""Live: a camera stream in, people on the floor plan, events and a web page out, as the frames arrive
(``ray3d live``; ``run_live``). The frame source (``source``), who is where causally (``people``), the site's
events as they happen (``events``), the event log and webhook (``outputs``), the page (``server``) and the loop
that joins them (``runner``)."""
