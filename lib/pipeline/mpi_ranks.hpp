#pragma once
// The ranks of one MPI bake and the few collectives it needs (linebake-mpi, docs/mpi.md).

#include <mpi.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "cache/cache.hpp"
#include "core/error.hpp"
#include "core/interrupt.hpp"

namespace linebake {

// The ranks of one bake and the few collectives it needs.
struct Ranks {
  MPI_Comm comm;
  int rank = 0, size = 1;

  explicit Ranks(MPI_Comm c) : comm(c) {
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &size);
  }
  std::vector<std::string> allgather(const std::string& mine) const {
    const int n = int(mine.size());
    std::vector<int> sizes(static_cast<size_t>(size)), displs(static_cast<size_t>(size));
    MPI_Allgather(&n, 1, MPI_INT, sizes.data(), 1, MPI_INT, comm);
    int total = 0;
    for (int r = 0; r < size; ++r) displs[size_t(r)] = total, total += sizes[size_t(r)];
    std::string all(size_t(total), '\0');
    MPI_Allgatherv(mine.data(), n, MPI_CHAR, all.data(), sizes.data(), displs.data(), MPI_CHAR,
                   comm);
    std::vector<std::string> out;
    for (int r = 0; r < size; ++r)
      out.push_back(all.substr(size_t(displs[size_t(r)]), size_t(sizes[size_t(r)])));
    return out;
  }
  void any(std::string& bytes) const {
    MPI_Allreduce(MPI_IN_PLACE, bytes.data(), int(bytes.size()), MPI_BYTE, MPI_BOR, comm);
  }
  uint64_t sum(uint64_t v) const {
    uint64_t out = 0;
    MPI_Allreduce(&v, &out, 1, MPI_UINT64_T, MPI_SUM, comm);
    return out;
  }
  void send(const std::string& text, int to) const {
    const uint64_t n = text.size();
    MPI_Send(&n, 1, MPI_UINT64_T, to, 0, comm);
    MPI_Send(text.data(), int(n), MPI_CHAR, to, 1, comm);
  }
  std::string receive(int from) const {
    uint64_t n = 0;
    MPI_Recv(&n, 1, MPI_UINT64_T, from, 0, comm, MPI_STATUS_IGNORE);
    std::string text(n, '\0');
    MPI_Recv(text.data(), int(n), MPI_CHAR, from, 1, comm, MPI_STATUS_IGNORE);
    return text;
  }
  // A binomial tree in rank order: at each level a rank takes the joined pieces of the ranks
  // after it, so rank 0 ends with every piece joined in order; what `finish` makes of that goes
  // to every rank, or its error does.
  std::string reduce(std::string mine, const ParallelWrite::Join& join,
                     const ParallelWrite::Finish& finish) const {
    for (int step = 1; step < size; step <<= 1) {
      if (rank % (2 * step) == 0) {
        if (rank + step < size) mine = join(mine, receive(rank + step));
      } else {
        send(mine, rank - step);
        break;
      }
    }
    std::string result;
    if (rank == 0) {
      try {
        result = '+' + finish(mine);
      } catch (const std::exception& e) {
        result = std::string("-") + e.what();
      }
    }
    result = broadcast(result);
    if (result.empty() || result[0] != '+') throw Error(result.empty() ? "" : result.substr(1));
    return result.substr(1);
  }
  // Every rank's `mine` (the same count on every rank), in rank order, on every rank.
  std::vector<uint64_t> allgather(const std::vector<uint64_t>& mine) const {
    std::vector<uint64_t> all(mine.size() * size_t(size));
    MPI_Allgather(mine.data(), int(mine.size()), MPI_UINT64_T, all.data(), int(mine.size()),
                  MPI_UINT64_T, comm);
    return all;
  }
  // Every rank's values, in rank order, on rank 0 (empty elsewhere).
  std::vector<uint64_t> gather(const std::vector<uint64_t>& mine) const {
    const int n = int(mine.size());
    std::vector<int> counts(static_cast<size_t>(size)), displs(static_cast<size_t>(size));
    MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, comm);
    int total = 0;
    for (int r = 0; r < size; ++r) displs[size_t(r)] = total, total += counts[size_t(r)];
    std::vector<uint64_t> all(rank == 0 ? size_t(total) : 0);
    MPI_Gatherv(mine.data(), n, MPI_UINT64_T, all.data(), counts.data(), displs.data(),
                MPI_UINT64_T, 0, comm);
    return all;
  }
  std::string broadcast(std::string text, int root = 0) const {
    uint64_t n = text.size();
    MPI_Bcast(&n, 1, MPI_UINT64_T, root, comm);
    text.resize(n);
    MPI_Bcast(text.data(), int(n), MPI_CHAR, root, comm);
    return text;
  }
  double max_value(double v) const {
    double out = 0;
    MPI_Allreduce(&v, &out, 1, MPI_DOUBLE, MPI_MAX, comm);
    return out;
  }
  uint64_t min(uint64_t v) const {
    uint64_t out = 0;
    MPI_Allreduce(&v, &out, 1, MPI_UINT64_T, MPI_MIN, comm);
    return out;
  }
  uint64_t max(uint64_t v) const {
    uint64_t out = 0;
    MPI_Allreduce(&v, &out, 1, MPI_UINT64_T, MPI_MAX, comm);
    return out;
  }
  std::vector<uint64_t> sum(std::vector<uint64_t> v) const {
    MPI_Allreduce(MPI_IN_PLACE, v.data(), int(v.size()), MPI_UINT64_T, MPI_SUM, comm);
    return v;
  }
  // Sum over the ranks before this one.
  uint64_t exclusive_sum(uint64_t v) const {
    uint64_t out = 0;
    MPI_Exscan(&v, &out, 1, MPI_UINT64_T, MPI_SUM, comm);
    return rank == 0 ? 0 : out;
  }

  // Runs a step that involves no other rank and agrees on its outcome: an error on any rank is
  // thrown on every rank, naming the lowest failing rank, with its kind (input, output, usage,
  // budget, an interruption, other).
  void agree(const std::function<void()>& step) const {
    char kind = 0;
    std::string message;
    try {
      step();
    } catch (const InputError& e) {
      // The file, the place and the message apart, to be put together again with the rank.
      const std::string prefix = e.file() + (e.where().empty() ? "" : ": " + e.where()) + ": ";
      kind = 'i', message = e.file() + '\x1f' + e.where() + '\x1f' +
                            std::string(e.what()).substr(prefix.size());
    } catch (const OutputError& e) {
      kind = 'o', message = e.file() + '\x1f' + e.detail();
    } catch (const Interrupted& e) {
      kind = 's', message = std::to_string(e.signal());
    } catch (const UsageError& e) {  // exit 1 as in linebake bake (it had been 4, a plain Error)
      kind = 'u', message = e.what();
    } catch (const BudgetExceeded& e) {
      kind = 'b', message = e.what();
    } catch (const std::exception& e) {
      kind = 'e', message = e.what();
    }
    const std::vector<std::string> all = allgather(kind ? std::string(1, kind) + message : "");
    for (int r = 0; r < size; ++r) {
      const std::string& m = all[size_t(r)];
      if (m.empty()) continue;
      const std::string rank_name = "rank " + std::to_string(r) + ": ";
      const std::string text = rank_name + m.substr(1);
      const auto field = [&](int i) {
        size_t begin = 1;
        for (int k = 0; k < i; ++k) begin = m.find('\x1f', begin) + 1;
        return m.substr(begin, m.find('\x1f', begin) - begin);
      };
      switch (m[0]) {
        case 'i':
          throw InputError(rank_name + field(0), field(1), field(2));
        case 'o':
          throw OutputError(rank_name + field(0), field(1));
        case 's':
          throw Interrupted(std::stoi(m.substr(1)));
        case 'u':
          throw UsageError(text);
        case 'b':
          throw BudgetExceeded(text);
        default:
          throw Error(text);
      }
    }
  }
};

}  // namespace linebake
