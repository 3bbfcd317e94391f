"""The service's endpoints, one module per resource; :mod:`globe.service.app` includes them all."""

from globe.service.routes import dashboard, feedback, health, households, model, observations, predictions, stats

ROUTERS = (health.router, households.router, observations.router, predictions.router, feedback.router,
           stats.router, model.router, dashboard.router)

__all__ = ["ROUTERS"]
