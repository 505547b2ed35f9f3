/* errors.js - SdfError, the one error type for what sdfd refused: over HTTP from the JSON
 * error body, over the binary protocol from an ERROR frame; both carry the same HTTP status
 * and code (docs/api.md's table), so callers handle one type whichever transport they use. */

export class SdfError extends Error {
  /**
   * @param {number} status the HTTP status (the binary protocol's ERROR carries it too)
   * @param {string} code e.g. "ENOTFOUND", "EINVAL"
   * @param {string} message the server's message
   */
  constructor(status, code, message) {
    super(message);
    this.name = 'SdfError';
    this.status = status;
    this.code = code;
  }

  toString() {
    return `SdfError: ${this.status} ${this.code}: ${this.message}`;
  }
}
