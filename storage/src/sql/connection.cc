#include "sql/connection.h"

namespace ambdiag::storage::detail {

Transaction::Transaction(Connection& db, Kind kind) : db_(&db), kind_(kind) {
  if (db.in_transaction()) {
    if (kind == Kind::read) return;  // joins the outer one
    db.exec("SAVEPOINT ambdiag_nested", "savepoint");
    owns_ = savepoint_ = true;
    return;
  }
  db.exec(db.begin_sql(kind), "begin transaction");
  owns_ = true;
}

Transaction::~Transaction() {
  if (!owns_) return;
  // No throw from a destructor. A savepoint's rollback fails harmlessly if
  // the database already rolled back the whole transaction (I/O error, disk
  // full, a lost connection).
  if (savepoint_)
    db_->exec_quietly("ROLLBACK TO ambdiag_nested; RELEASE ambdiag_nested");
  else
    db_->exec_quietly("ROLLBACK");
}

void Transaction::commit() {
  if (!owns_) return;
  db_->exec(savepoint_ ? "RELEASE ambdiag_nested" : "COMMIT", "commit");
  owns_ = false;
  if (!savepoint_ && kind_ == Kind::write) db_->committed();
}

}  // namespace ambdiag::storage::detail
