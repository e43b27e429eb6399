// Historian: API tokens (table tokens; schema v4). A token is "amb_" and 43
// base64url characters (32 random bytes from the kernel); the file holds
// only its SHA-256, so a copy of the database gives no one a token.
#include <sys/random.h>

#include <cerrno>
#include <cstring>

#include "ambdiag/core/sha256.h"
#include "ambdiag/storage/historian.h"
#include "historian_impl.h"

namespace ambdiag::storage {

std::string to_string(Role r) {
  switch (r) {
    case Role::viewer: return "viewer";
    case Role::operator_: return "operator";
    case Role::engineer: return "engineer";
    case Role::admin: return "admin";
  }
  return "viewer";
}

std::optional<Role> role_from(const std::string& s) {
  for (auto r : {Role::viewer, Role::operator_, Role::engineer, Role::admin})
    if (to_string(r) == s) return r;
  return std::nullopt;
}

namespace {

constexpr std::size_t kMaxNameLength = 64;

// Names go into logs, alarm histories and command lines: a small alphabet.
void check_token_name(const std::string& name) {
  if (name.empty() || name.size() > kMaxNameLength)
    throw InputError("token name " + quoted(name) + ": must be 1 to " + std::to_string(kMaxNameLength) +
                     " characters");
  for (const char c : name) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' ||
                    c == '_' || c == '@' || c == '-';
    if (!ok)
      throw InputError("token name " + quoted(name) + ": only letters, digits and . _ @ - are allowed");
  }
}

std::string random_secret() {
  std::uint8_t bytes[32];
  std::size_t got = 0;
  while (got < sizeof bytes) {
    const ssize_t n = ::getrandom(bytes + got, sizeof bytes - got, 0);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw StorageError(std::string("add_token: getrandom: ") + std::strerror(errno));
    }
    got += static_cast<std::size_t>(n);
  }
  // base64url without padding (RFC 4648, section 5): 32 bytes -> 43 characters.
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_";
  std::string s = "amb_";
  std::uint32_t acc = 0;
  int bits = 0;
  for (const std::uint8_t b : bytes) {
    acc = (acc << 8) | b;
    bits += 8;
    while (bits >= 6) {
      bits -= 6;
      s += kAlphabet[(acc >> bits) & 63];
    }
  }
  if (bits > 0) s += kAlphabet[(acc << (6 - bits)) & 63];
  std::memset(bytes, 0, sizeof bytes);
  return s;
}

std::span<const std::uint8_t> as_bytes(const Sha256Digest& d) { return {d.data(), d.size()}; }

TokenInfo read_token_row(const Stmt& s) {
  return {s.col_text(0), role_from(s.col_text(1)).value_or(Role::viewer), s.col_text(2), s.col_opt_text(3)};
}

}  // namespace

std::string Historian::add_token(const std::string& name, Role role) {
  impl_->require_writer("add_token");
  check_token_name(name);
  std::string secret = random_secret();
  const Sha256Digest hash = sha256(secret);
  const std::string role_text = to_string(role), now = now_utc();
  Transaction tx(impl_->db, Transaction::Kind::write);
  impl_->lock(Impl::LockSpace::token, name);  // no other add of the name between the check and the upsert
  auto& held = impl_->stmt("SELECT revoked_at IS NULL FROM tokens WHERE name = ?");
  held.bind(1, name);
  const bool exists = held.step();
  const bool active = exists && held.col_int(0) != 0;
  held.reset();
  if (active) throw InputError("token name " + quoted(name) + " is taken (revoke it first)");
  // A revoked name may be given again: its row takes the new token (the old
  // secret's hash goes, so the old secret stays refused).
  impl_->stmt(
          "INSERT INTO tokens (name, role, sha256, created_at, revoked_at) VALUES (?, ?, ?, ?, NULL) "
          "ON CONFLICT (name) DO UPDATE SET role = excluded.role, sha256 = excluded.sha256, "
          "created_at = excluded.created_at, revoked_at = NULL")
      .bind(1, name)
      .bind(2, role_text)
      .bind_blob(3, as_bytes(hash))
      .bind(4, now)
      .run();
  tx.commit();
  return secret;
}

std::optional<TokenInfo> Historian::find_token(const std::string& secret) {
  if (secret.empty()) return std::nullopt;
  const Sha256Digest hash = sha256(secret);
  auto& s = impl_->stmt("SELECT name, role, created_at, revoked_at FROM tokens WHERE sha256 = ? AND revoked_at IS NULL");
  s.bind_blob(1, as_bytes(hash));
  if (!s.step()) return std::nullopt;
  auto t = read_token_row(s);
  s.reset();
  return t;
}

std::vector<TokenInfo> Historian::list_tokens() {
  auto& s = impl_->stmt("SELECT name, role, created_at, revoked_at FROM tokens ORDER BY name");
  std::vector<TokenInfo> out;
  while (s.step()) out.push_back(read_token_row(s));
  return out;
}

bool Historian::revoke_token(const std::string& name) {
  impl_->require_writer("revoke_token");
  Transaction tx(impl_->db, Transaction::Kind::write);
  impl_->stmt("UPDATE tokens SET revoked_at = ? WHERE name = ? AND revoked_at IS NULL")
      .bind(1, now_utc())
      .bind(2, name)
      .run();
  if (impl_->db.changes() != 1) return false;
  tx.commit();
  return true;
}

}  // namespace ambdiag::storage
