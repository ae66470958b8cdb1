"""springfit_client: a Python client of springfitd, the springfit identification daemon.

Standard library only. The protocol is JSON-RPC 2.0 over TCP (proto/RPC.md); importing
meshes and exporting models run the springfit program.

    from springfit_client import Client
    with Client("127.0.0.1:7117", token_file="token") as sf:
        job_id = sf.submit("scene.json", label="nightly", seed=7)
        job = sf.watch(job_id, on_progress=lambda p: print(p.generation, p.rms_error))
        print(job.state, job.verdict, job.rms_error)
"""

from .client import DEFAULT_SERVER, DEFAULT_TIMEOUT, Client, parse_server_address
from .errors import (BUSY, INTERNAL_ERROR, INVALID_PARAMS, INVALID_REQUEST, INVALID_SCENE,
                     LIMIT_EXCEEDED, METHOD_NOT_FOUND, NO_SUCH_JOB, PARSE_ERROR, STORE_CORRUPT,
                     STORE_UNAVAILABLE, UNAUTHORIZED, WRONG_STATE, CliError, RpcError,
                     ServerConnectionError, ServerTimeout, SpringfitError, WatchTimeout)
from .records import (DOUBTFUL, FINAL_STATES, UNMET_REQUEST, UNUSABLE, USABLE, Improvement, Job,
                      Outcome, Phase,
                      Progress, Result, ServerInfo, Submission, TraceRow)

__version__ = "1.0.0"

__all__ = [
    "Client", "DEFAULT_SERVER", "DEFAULT_TIMEOUT", "parse_server_address",
    "SpringfitError", "RpcError", "ServerConnectionError", "ServerTimeout", "WatchTimeout",
    "CliError", "PARSE_ERROR", "INVALID_REQUEST", "METHOD_NOT_FOUND", "INVALID_PARAMS",
    "INTERNAL_ERROR", "UNAUTHORIZED", "NO_SUCH_JOB", "INVALID_SCENE", "LIMIT_EXCEEDED", "BUSY",
    "WRONG_STATE", "STORE_UNAVAILABLE", "STORE_CORRUPT",
    "USABLE", "UNMET_REQUEST", "UNUSABLE", "DOUBTFUL", "FINAL_STATES", "Job", "Outcome", "Phase", "Progress",
    "TraceRow", "Result", "ServerInfo", "Submission", "Improvement",
]
