// Read connections to the historian, one per worker thread at most, opened
// on first use and lent out per request.
#pragma once

#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "ambdiag/storage/historian.h"

namespace ambdiag::server::detail {

class ReaderPool {
 public:
  ReaderPool(std::string db_path, int max_readers);

  class Lease {
   public:
    Lease(ReaderPool* pool, std::unique_ptr<storage::Historian> h) : pool_(pool), h_(std::move(h)) {}
    Lease(Lease&&) noexcept = default;
    Lease& operator=(Lease&&) = delete;
    ~Lease();
    storage::Historian& operator*() { return *h_; }
    storage::Historian* operator->() { return h_.get(); }

   private:
    ReaderPool* pool_;
    std::unique_ptr<storage::Historian> h_;
  };
  // Blocks while max_readers are lent out.
  Lease acquire();

 private:
  std::string path_;
  int max_;
  int opened_ = 0;
  std::mutex m_;
  std::condition_variable cv_;
  std::vector<std::unique_ptr<storage::Historian>> idle_;
};

}  // namespace ambdiag::server::detail
