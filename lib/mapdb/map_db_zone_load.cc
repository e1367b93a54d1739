// The map database's zone loads: one read transaction, one statement stepping over the zone's
// members, each payload read through the incremental blob handle straight into its slot, in one
// call (LoadZone) or time-sliced (BeginZoneLoad / StepZoneLoad / AbortZoneLoad). The invariants
// are listed at the top of map_db.cc.
#include <algorithm>
#include <cassert>
#include <chrono>
#include <cstddef>
#include <string>

#include "mapdb/map_db.h"
#include "mapdb/map_db_internal.h"

namespace zm {

Status MapDb::Impl::EndZoneLoad(bool commit_it) {
  sqlite3_stmt* members = zone_members.get();
  sqlite3_reset(members);
  sqlite3_clear_bindings(members);
  blob.reset();
  cursor = Cursor{};
  sqlite3_stmt* end = commit_it ? commit.get() : rollback.get();
  const int rc = sqlite3_step(end);
  sqlite3_reset(end);
  if (commit_it && rc != SQLITE_DONE) {
    // A failed COMMIT leaves the transaction open: roll it back so the next load can begin.
    const Status st = FromSqlite(rc, db.get(), "COMMIT");
    sqlite3_step(rollback.get());
    sqlite3_reset(rollback.get());
    return st;
  }
  return Status::Ok();
}

Status MapDb::Impl::Advance() {
  const int rc = sqlite3_step(zone_members.get());
  cursor.row_ready = rc == SQLITE_ROW;
  if (rc == SQLITE_ROW || rc == SQLITE_DONE) return Status::Ok();
  return FromSqlite(rc, db.get(), "stepping the members of zone " + std::to_string(cursor.zone.value));
}

Status MapDb::Impl::MissingPayload(int brc, KeyframeId id) const {
  const std::string zone = std::to_string(cursor.zone.value);
  if ((brc & 0xff) == SQLITE_NOMEM) {  // SQLite's heap limit, not a missing row
    return ResourceExhausted(Kf(id) + " of zone " + zone + " in " + path +
                             ": SQLite out of memory opening its payload (" + sqlite3_errstr(brc) + ")");
  }
  return Corrupt(Kf(id) + " of zone " + zone + " in " + path + ": no readable payload row (" +
                 sqlite3_errstr(brc) + ": " + sqlite3_errmsg(db.get()) + ")");
}

Status MapDb::Impl::PositionBlob(KeyframeId id) {
  if (!blob) {
    sqlite3_blob* raw = nullptr;
    const int brc = sqlite3_blob_open(db.get(), "main", "payload", "blob", id.value, 0, &raw);
    blob.reset(raw);
    if (brc != SQLITE_OK) return MissingPayload(brc, id);
    return Status::Ok();
  }
  const int brc = sqlite3_blob_reopen(blob.get(), id.value);
  return brc == SQLITE_OK ? Status::Ok() : MissingPayload(brc, id);
}

Status MapDb::Impl::Step(const LoadBudget& budget, LoadStats& st) {
  Arena& arena = *cursor.arena;
  LoadSink& sink = *cursor.sink;
  const bool timed = budget.deadline != std::chrono::steady_clock::time_point::max();
  std::uint32_t loaded = 0;
  std::uint64_t bytes_loaded = 0;
  while (cursor.row_ready) {
    // Count and time are checked before Wants(), so a member is asked once unless the byte
    // budget (which needs the blob's size) stops the step.
    if (loaded > 0 && (loaded >= budget.max_keyframes ||
                       (timed && std::chrono::steady_clock::now() >= budget.deadline))) {
      return Status::Ok();
    }
    const KeyframeId id{sqlite3_column_int64(zone_members.get(), 0)};
    if (!sink.Wants(id)) {
      ++st.skipped;
      ZM_RETURN_IF_ERROR(Advance());
      continue;
    }
    ZM_RETURN_IF_ERROR(PositionBlob(id));
    const int bytes = sqlite3_blob_bytes(blob.get());
    if (bytes < 0 || static_cast<std::uint64_t>(bytes) > arena.slot_bytes()) {
      return OutOfRange(Kf(id) + " in " + path + ": payload blob of " + std::to_string(bytes) +
                        " bytes is larger than the arena slot of " +
                        std::to_string(arena.slot_bytes()) + " bytes");
    }
    if (loaded > 0 && bytes_loaded + static_cast<std::uint64_t>(bytes) > budget.max_bytes) {
      return Status::Ok();  // the row stays ready: the next step starts with this member
    }
    const auto slot = arena.TryAcquire();
    if (!slot) {
      return ResourceExhausted("arena full (" + std::to_string(arena.capacity()) +
                               " slots) loading " + Kf(id) + " of zone " +
                               std::to_string(cursor.zone.value) + " after " +
                               std::to_string(cursor.delivered) + " keyframes of this zone");
    }
    std::span<std::byte> dst = arena.Slot(*slot).first(static_cast<std::size_t>(bytes));
    Count(st, 0, 1, 0);
    StreamedChecksum checksum(options.verify_checksums);
    int rrc = SQLITE_OK;
    // The header first (it says which checksum), then the body piece by piece.
    for (std::size_t done = 0; done < dst.size() && rrc == SQLITE_OK;) {
      const std::size_t n = std::min(done == 0 ? kPayloadHeaderBytes : kCopyChunkBytes, dst.size() - done);
      rrc = sqlite3_blob_read(blob.get(), dst.data() + done, static_cast<int>(n), static_cast<int>(done));
      checksum.Feed(dst.first(done + n), done);
      done += n;
    }
    auto landed = rrc == SQLITE_OK
                      ? Land(id, arena.Slot(*slot), static_cast<std::size_t>(bytes), checksum)
                      : Result<std::uint32_t>(FromSqlite(rrc, db.get(), "reading the payload of " + Kf(id)));
    if (!landed.ok()) {
      arena.Release(*slot);
      return landed.status();
    }
    sink.Loaded(id, *slot, *landed);
    CountBytes(st, static_cast<std::uint32_t>(bytes));
    ++loaded;
    ++cursor.delivered;
    bytes_loaded += static_cast<std::uint64_t>(bytes);
    ZM_RETURN_IF_ERROR(Advance());
  }
  return Status::Ok();
}

Result<LoadStats> MapDb::BeginZoneLoad(ZoneId zone, Arena& arena, LoadSink& sink) {
  const auto t0 = std::chrono::steady_clock::now();
  Impl& im = *impl_;
  ZM_RETURN_IF_ERROR(im.RefuseWhileZoneLoad("loading zone " + std::to_string(zone.value)));
  if (zone.value < 0 || static_cast<std::uint64_t>(zone.value) >= im.meta.zone_count) {
    return NotFound("zone " + std::to_string(zone.value) + " is not in " + im.path + " (" +
                    std::to_string(im.meta.zone_count) + " zones)");
  }
  sqlite3* db = im.db.get();
  LoadStats st;
  const int rc = sqlite3_step(im.begin.get());
  sqlite3_reset(im.begin.get());
  if (rc != SQLITE_DONE) return FromSqlite(rc, db, "BEGIN for zone " + std::to_string(zone.value));
  im.cursor.zone = zone;
  im.cursor.arena = &arena;
  im.cursor.sink = &sink;
  im.Count(st, 1, 0, 1);
  // The first step of the member statement takes the read lock: from here on the load sees
  // one state of the map, however many steps it takes.
  sqlite3_bind_int(im.zone_members.get(), 1, zone.value);
  Status status = im.Advance();
  if (!status.ok()) {
    (void)im.EndZoneLoad(/*commit_it=*/false);
    return status;
  }
  st.ms = MsSince(t0);
  return st;
}

Result<ZoneLoadStep> MapDb::StepZoneLoad(const LoadBudget& budget) {
  const auto t0 = std::chrono::steady_clock::now();
  Impl& im = *impl_;
  if (im.cursor.zone == kNoZone) {
    return FailedPrecondition("no zone load in flight on " + im.path + " (BeginZoneLoad first)");
  }
  ZoneLoadStep step;
  Status status = im.Step(budget, step.stats);
  if (status.ok() && !im.cursor.row_ready) {
    status = im.EndZoneLoad(/*commit_it=*/true);
    step.done = true;
  }
  if (!status.ok()) {
    if (im.cursor.zone != kNoZone) (void)im.EndZoneLoad(/*commit_it=*/false);
    return status;
  }
  step.stats.ms = MsSince(t0);
  return step;
}

void MapDb::AbortZoneLoad() {
  if (impl_->cursor.zone != kNoZone) (void)impl_->EndZoneLoad(/*commit_it=*/false);
}

ZoneId MapDb::ZoneLoadInFlight() const { return impl_->cursor.zone; }

Result<LoadStats> MapDb::LoadZone(ZoneId zone, Arena& arena, LoadSink& sink) {
  const auto t0 = std::chrono::steady_clock::now();
  ZM_ASSIGN_OR_RETURN(LoadStats st, BeginZoneLoad(zone, arena, sink));
  ZM_ASSIGN_OR_RETURN(const ZoneLoadStep step, StepZoneLoad(LoadBudget{}));
  assert(step.done && "an unlimited step finishes the load");
  st += step.stats;
  st.ms = MsSince(t0);
  return st;
}

}  // namespace zm
