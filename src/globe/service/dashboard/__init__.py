"""The household dashboard served by ``globe serve`` under ``/dashboard``: server-rendered pages
(Jinja2 templates and SVG charts drawn here), a login that exchanges an API token for a signed
session cookie, and nothing fetched from anywhere but the service itself."""
