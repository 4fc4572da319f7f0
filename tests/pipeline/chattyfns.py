"""A job kind whose items do what third-party libraries do in our stages: initialise Warp (its
banner), load a Warp kernel module ("Module ... load on device 'cpu' took ... ms"), warn through
Python's warnings module, log through a library logger, print, and write to fd 2 from outside
Python. Used by the console / job.log test of the CLI."""

from __future__ import annotations

import logging
import os
import warnings

from pydantic import BaseModel, ConfigDict, Field

from pipeline.types import ItemContext, JobKind, PlanContext, WorkItem

log = logging.getLogger("stages.chatty_test")   # one of our loggers: its records are not deduplicated


class ChattyWarning(UserWarning):
    pass


class ChattyConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    n: int = Field(ge=1)


class ChattyParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    index: int


class ChattyResult(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    total: float


def chatty(params: ChattyParams, ctx: ItemContext) -> ChattyResult:
    import warp as wp

    wp.init()

    @wp.kernel
    def add_one(a: wp.array(dtype=float)):
        a[wp.tid()] += 1.0

    a = wp.zeros(4, dtype=float, device="cpu")
    wp.launch(add_one, dim=4, inputs=[a], device="cpu")
    warnings.warn("a third-party warning, repeated by every item", ChattyWarning, stacklevel=1)
    logging.getLogger("thirdparty.lib").warning("a third-party logger warning (item %d)", params.index)
    print(f"a third-party print from item {params.index}")
    os.write(2, b"a native write to stderr\n")
    log.info("chatty item %d done", params.index)
    return ChattyResult(total=float(a.numpy().sum()))


def plan_chatty(cfg: ChattyConfig, pctx: PlanContext) -> list[WorkItem]:
    return [WorkItem(item_id=f"c{i}", fn="chattyfns:chatty", params=ChattyParams(index=i)) for i in range(cfg.n)]


CHATTY_KIND = JobKind(name="chatty", config=ChattyConfig, plan=plan_chatty, description="chatter (test kind)")
