"""The exceptions of springfit_client, and the error codes of proto/RPC.md ("Errors")."""

__all__ = [
    "SpringfitError", "RpcError", "ServerConnectionError", "ServerTimeout", "WatchTimeout",
    "CliError", "PARSE_ERROR", "INVALID_REQUEST", "METHOD_NOT_FOUND", "INVALID_PARAMS",
    "INTERNAL_ERROR", "UNAUTHORIZED", "NO_SUCH_JOB", "INVALID_SCENE", "LIMIT_EXCEEDED", "BUSY",
    "WRONG_STATE", "STORE_UNAVAILABLE", "STORE_CORRUPT",
]

# JSON-RPC error codes springfitd answers with (proto/RPC.md, "Errors").
PARSE_ERROR = -32700
INVALID_REQUEST = -32600
METHOD_NOT_FOUND = -32601
INVALID_PARAMS = -32602        # data.path: the field, e.g. "params.job_id"
INTERNAL_ERROR = -32603        # data.incident: its number in the daemon's log
UNAUTHORIZED = -32001          # no token presented, or a wrong one
NO_SUCH_JOB = -32002           # data.job_id
INVALID_SCENE = -32003         # data.path: the field inside the scene
LIMIT_EXCEEDED = -32004        # data.limit, data.value, data.max
BUSY = -32005                  # queue full, too many connections, shutting down
WRONG_STATE = -32006           # data.state: the job's state
STORE_UNAVAILABLE = -32007     # nothing stored; retry later (submit with its idempotency key)
STORE_CORRUPT = -32008         # data.incident

_NAMES = {
    PARSE_ERROR: "parse error", INVALID_REQUEST: "invalid request",
    METHOD_NOT_FOUND: "method not found", INVALID_PARAMS: "invalid params",
    INTERNAL_ERROR: "internal error", UNAUTHORIZED: "unauthorized", NO_SUCH_JOB: "no such job",
    INVALID_SCENE: "invalid scene", LIMIT_EXCEEDED: "limit exceeded", BUSY: "busy",
    WRONG_STATE: "wrong state", STORE_UNAVAILABLE: "store unavailable",
    STORE_CORRUPT: "store corrupt",
}


class SpringfitError(Exception):
    """Base class of every error this package raises on its own."""


class RpcError(SpringfitError):
    """springfitd answered a request with a JSON-RPC error object.

    code: the error code (the constants of this module, e.g. NO_SUCH_JOB); message: the
    server's words; data: the error's `data` member (a dict, {} when absent); method: the
    request's method.
    """

    def __init__(self, code, message, data=None, method=None):
        self.code = code
        self.message = message
        self.data = data if isinstance(data, dict) else ({} if data is None else {"value": data})
        self.method = method
        super().__init__(code, message)

    @property
    def name(self):
        """The code's meaning in a few words ("no such job"), or "error N"."""
        return _NAMES.get(self.code, f"error {self.code}")

    def __str__(self):
        where = f"{self.method}: " if self.method else ""
        return f"{where}{self.message} ({self.name}, {self.code})"


class ServerConnectionError(SpringfitError, ConnectionError):
    """springfitd cannot be reached, the connection broke, or what it sent is not JSON-RPC.

    The Client drops the connection; its next call connects anew (and authenticates again).
    """


class ServerTimeout(ServerConnectionError, TimeoutError):
    """springfitd did not accept the connection, or did not answer a request, within the
    Client's `timeout` seconds. The answer may still come: a request that changes something
    (a submit) may have been carried out (retry a submit with its idempotency key)."""


class WatchTimeout(SpringfitError, TimeoutError):
    """Client.watch(timeout=...) passed its time before the job finished. The job goes on
    running on the server; `job` is the job as last seen (None when nothing was seen)."""

    def __init__(self, message, job=None):
        super().__init__(message)
        self.job = job


class CliError(SpringfitError):
    """The springfit program (import, export) failed: `returncode` is its exit code
    (README.md, "Exit codes"), `stderr` what it said, `command` its command line."""

    def __init__(self, command, returncode, stderr):
        self.command = list(command)
        self.returncode = returncode
        self.stderr = stderr
        text = stderr.strip().splitlines()
        last = text[-1] if text else "(no message)"
        super().__init__(f"{' '.join(self.command[:2])} exited with {returncode}: {last}")
