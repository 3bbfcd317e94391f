"""What the routes depend on, importable so that tests can override it
(``app.dependency_overrides[deps.get_registry] = ...``): the registry of households and the
caller, authenticated from the ``Authorization`` header and authorised per route.

They are ``async`` because they do not block (the caller was authenticated by the guard): FastAPI
runs a plain function dependency in a worker thread, and three such hops cost each request
about 0.1 ms."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from globe.service import auth
from globe.service.registry import Registry


async def get_registry(request: Request) -> Registry:
    """The households this process serves (built in the app's lifespan)."""
    return request.app.state.registry


async def get_caller(request: Request, registry: Annotated[Registry, Depends(get_registry)]) -> auth.Caller:
    """Who sends the request (401 without a known, unrevoked token): authenticated by the
    :class:`~globe.service.guard.Guard` from the headers before the body was read."""
    caller = getattr(request.state, "caller", None)
    if isinstance(caller, auth.Caller):
        return caller
    return auth.authenticate(registry.store, request.headers.get("authorization"))


async def require_admin(caller: Annotated[auth.Caller, Depends(get_caller)]) -> auth.Caller:
    """An admin token (403 for a household token)."""
    caller.require_admin()
    return caller


async def require_member(name: str, caller: Annotated[auth.Caller, Depends(get_caller)]) -> auth.Caller:
    """An admin token, or the token of household ``name`` (403 for another household's)."""
    caller.require_household(name)
    return caller


RegistryDep = Annotated[Registry, Depends(get_registry)]
AdminDep = Annotated[auth.Caller, Depends(require_admin)]
MemberDep = Annotated[auth.Caller, Depends(require_member)]
