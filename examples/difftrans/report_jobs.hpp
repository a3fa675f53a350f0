// The runs behind `difftrans report`: each is one difftrans subcommand in a
// folder of its own under the work folder, started as a child process of
// this program, timed (wall, CPU, peak memory) and recorded. A run whose
// record says it finished with the same inputs is reused, so a stopped
// report goes on where it stopped.
#pragma once

#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "command.hpp"
#include "long_run.hpp"
#include "difftrans/io/json.hpp"

extern char** environ;

namespace difftrans::cli::report {

namespace fs = std::filesystem;

// Written into every run's work folder path: the placeholder is replaced by
// the work folder when the run starts, and kept in the hash so that moving
// the work folder keeps its runs.
inline const std::string work_placeholder = "@WORK";

// One run: `difftrans ARGS`, in WORK/ID. "@WORK" in an argument stands for
// the work folder; "@OUT" for this run's output folder (WORK/ID/out).
struct Job {
  std::string id;                 // a folder path under the work folder, e.g. "spot-clear/stage1"
  std::string title;              // what it is, for the progress lines and the page
  std::vector<std::string> args;  // the difftrans arguments
  std::string copy_from;          // a run whose output folder is copied into this one's first ("" for none)
  std::vector<std::string> after; // the runs it reads (their hashes enter this one's)
};

// What a run did.
struct JobRecord {
  std::string id, hash, build, status;  // status: "done", "failed", "skipped"
  int exit_code = 0;
  bool reused = false;
  double wall_seconds = 0, cpu_seconds = 0, peak_memory_mb = 0;
  std::string command;  // the shell line that repeats it, from the work folder
  std::string stamp;    // which execution made the files (a run reading them records it)
  std::map<std::string, std::string> inputs;  // the stamps of the runs it read
  io::Json json() const {
    return {{"id", id},
            {"hash", hash},
            {"stamp", stamp},
            {"inputs", inputs},
            {"build", build},
            {"status", status},
            {"exit_code", exit_code},
            {"reused", reused},
            {"wall_seconds", wall_seconds},
            {"cpu_seconds", cpu_seconds},
            {"peak_memory_mb", peak_memory_mb},
            {"command", command}};
  }
};

inline std::uint64_t fnv1a(const std::string& bytes, std::uint64_t h = 14695981039346656037ull) {
  for (unsigned char c : bytes) h = (h ^ c) * 1099511628211ull;
  return h;
}

inline std::string hex64(std::uint64_t h) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

// This program, as the kernel holds it (the runs start the same bytes even
// when the file is rebuilt meanwhile), and a hash of its bytes: which build
// made a run.
inline fs::path self_executable() {
  const fs::path p = "/proc/self/exe";
  if (!fs::exists(p)) throw std::runtime_error("report: cannot find this program (/proc/self/exe)");
  return p;
}
inline std::string build_id(const fs::path& exe) {
  std::ifstream in(exe, std::ios::binary);
  std::uint64_t h = 14695981039346656037ull;
  char buf[1 << 16];
  while (in.read(buf, sizeof buf) || in.gcount() > 0) {
    h = fnv1a(std::string(buf, std::size_t(in.gcount())), h);
    if (!in) break;
  }
  return hex64(h);
}

// A shell word: quoted when it holds anything but safe characters.
inline std::string shell_word(const std::string& w) {
  bool safe = !w.empty();
  for (char c : w)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || std::string("@%+=:,./_-").find(c) != std::string::npos)) safe = false;
  if (safe) return w;
  std::string q = "'";
  for (char c : w) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

class Runner {
 public:
  Runner(fs::path work, bool rerun) : work_(fs::absolute(std::move(work))), rerun_(rerun), exe_(self_executable()) {
    build_ = build_id(exe_);
  }

  // The shell line that repeats a run from the work folder.
  std::string command_line(const Job& job) const {
    std::string cmd = "difftrans";
    for (const auto& a : job.args) {
      std::string shown = a;
      for (std::size_t p = shown.find("@OUT"); p != std::string::npos; p = shown.find("@OUT", p + 1))
        shown.replace(p, 4, job.id + "/out");
      for (std::size_t p = shown.find(work_placeholder + "/"); p != std::string::npos; p = shown.find(work_placeholder + "/", p))
        shown.erase(p, work_placeholder.size() + 1);
      cmd += " " + shell_word(shown);
    }
    if (!job.copy_from.empty())
      cmd = "mkdir -p " + job.id + " && rm -rf " + job.id + "/out && cp -r " + job.copy_from + "/out " + job.id + "/out && " + cmd;
    return cmd;
  }

  const fs::path& work() const { return work_; }
  const std::string& build() const { return build_; }
  fs::path folder(const std::string& id) const { return work_ / id; }
  fs::path out(const std::string& id) const { return work_ / id / "out"; }
  const std::map<std::string, JobRecord>& records() const { return records_; }
  const JobRecord* record(const std::string& id) const {
    const auto it = records_.find(id);
    return it == records_.end() ? nullptr : &it->second;
  }
  bool ok(const std::string& id) const {
    const JobRecord* r = record(id);
    return r && r->status == "done";
  }
  // The run's stdout (the subcommand's JSON result); null when it has none.
  io::Json result(const std::string& id) const {
    const fs::path p = folder(id) / "stdout.json";
    if (!ok(id) || !fs::exists(p) || fs::file_size(p) == 0) return nullptr;
    return io::read_json(p);
  }

  // Runs (or reuses) every job in order, one progress line each.
  void run_all(const std::vector<Job>& jobs) {
    fs::create_directories(work_);
    // a run's folder is removed before it is made again: none may hold another's
    for (const auto& a : jobs)
      for (const auto& b : jobs)
        if (&a != &b && (b.id == a.id || b.id.rfind(a.id + "/", 0) == 0))
          throw std::logic_error("report: run '" + b.id + "' would live inside run '" + a.id + "'");
    std::map<std::string, std::string> anchors;
    for (const auto& j : jobs) {
      std::string a;
      for (char c : j.id) a += std::isalnum(static_cast<unsigned char>(c)) ? c : '-';
      if (!anchors.emplace(a, j.id).second)
        throw std::logic_error("report: runs '" + anchors[a] + "' and '" + j.id + "' would share a link on the page");
    }
    const auto start = std::chrono::steady_clock::now();
    for (std::size_t i = 0; i < jobs.size(); ++i) {
      const Job& job = jobs[i];
      if (const int sig = stop_requested())
        throw Interrupted(sig, "report: stopped before " + job.title + "; finished runs are kept in " + work_.string() +
                                   ": the same command goes on from there");
      char head[64];
      std::snprintf(head, sizeof head, "report: [%zu/%zu] ", i + 1, jobs.size());
      JobRecord r = run(job);
      const double minutes = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / 60.0;
      std::string what = r.status == "done" ? (r.reused ? "reused" : "done in " + fixed_text(r.wall_seconds, 1) + " s")
                                            : r.status == "skipped" ? "skipped: a run it needs did not finish"
                                                                    : "FAILED (exit " + std::to_string(r.exit_code) + "), see " +
                                                                          (folder(job.id) / "log.txt").string();
      progress(std::string(head) + job.title + ": " + what + " (" + fixed_text(minutes, 1) + " min so far)");
      records_[job.id] = r;
    }
  }

 private:
  static std::string fixed_text(double v, int digits) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", digits, v);
    return buf;
  }

  std::string expand(const std::string& arg, const std::string& id) const {
    std::string s = arg;
    const auto replace = [&s](const std::string& from, const std::string& to) {
      for (std::size_t p = s.find(from); p != std::string::npos; p = s.find(from, p + to.size())) s.replace(p, from.size(), to);
    };
    replace("@OUT", (work_placeholder + "/" + id + "/out"));
    replace(work_placeholder, work_.string());
    return s;
  }

  std::string hash_of(const Job& job) const {
    std::string text = "difftrans report run v1\x1f" + job.id + "\x1f" + job.copy_from;
    for (const auto& a : job.args) text += "\x1f" + a;
    for (const auto& d : job.after) {
      const JobRecord* r = record(d);
      text += "\x1f" + d + "=" + (r ? r->hash : std::string("?"));
    }
    if (!job.copy_from.empty()) {
      const JobRecord* r = record(job.copy_from);
      text += "\x1f" "copy=" + (r ? r->hash : std::string("?"));
    }
    return hex64(fnv1a(text));
  }

  JobRecord run(const Job& job) {
    JobRecord r;
    r.id = job.id;
    r.hash = hash_of(job);
    r.build = build_;
    r.command = command_line(job);
    const fs::path dir = folder(job.id);
    const fs::path record_file = dir / "job.json";
    for (const auto& d : job.after)
      if (!ok(d)) {
        r.status = "skipped";
        return r;
      }
    if (!job.copy_from.empty() && !ok(job.copy_from)) {
      r.status = "skipped";
      return r;
    }
    for (const auto& d : job.after) r.inputs[d] = record(d)->stamp;
    if (!job.copy_from.empty()) r.inputs[job.copy_from] = record(job.copy_from)->stamp;
    bool resume = false;  // an interrupted reconstruct: its folder holds a checkpoint to go on from
    if (!rerun_ && fs::exists(record_file)) {
      try {
        const io::Json old = io::read_json(record_file);
        // a record without stamps (an earlier version's) read inputs that had none either
        std::map<std::string, std::string> read;
        if (old.contains("inputs") && old["inputs"].is_object())
          read = old["inputs"].get<std::map<std::string, std::string>>();
        else
          for (const auto& [d, stamp] : r.inputs) read[d] = "";
        const bool same_inputs = read == r.inputs;
        resume = old.value("hash", "") == r.hash && old.value("status", "") == "interrupted" && same_inputs &&
                 !job.args.empty() && job.args.front() == "reconstruct";
        if (old.value("hash", "") == r.hash && old.value("status", "") == "done" && same_inputs) {
          r.status = "done";
          r.reused = true;
          r.build = old.value("build", "");
          r.wall_seconds = old.value("wall_seconds", 0.0);
          r.cpu_seconds = old.value("cpu_seconds", 0.0);
          r.peak_memory_mb = old.value("peak_memory_mb", 0.0);
          r.stamp = old.value("stamp", "");
          return r;
        }
      } catch (const std::exception& e) {
        warn("report: " + record_file.string() + " unreadable (" + e.what() + "): the run is made again");
      }
    }
    if (!resume) {
      fs::remove_all(dir);
      fs::create_directories(dir);
      if (!job.copy_from.empty()) fs::copy(out(job.copy_from), out(job.id), fs::copy_options::recursive);
    }
    fs::remove(record_file);

    std::vector<std::string> args{exe_.string()};
    for (const auto& a : job.args) args.push_back(expand(a, job.id));
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    const std::string out_file = (dir / "stdout.json").string(), log_file = (dir / "log.txt").string();
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, out_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, log_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    // its own process group: Ctrl-C at a terminal reaches this program alone,
    // which passes it on once (below)
    posix_spawnattr_t attributes;
    posix_spawnattr_init(&attributes);
    posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETPGROUP);
    posix_spawnattr_setpgroup(&attributes, 0);
    const auto t0 = std::chrono::steady_clock::now();
    pid_t pid = 0;
    const int err = posix_spawn(&pid, exe_.c_str(), &actions, &attributes, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    posix_spawnattr_destroy(&attributes);
    if (err != 0) throw std::runtime_error("report: cannot start " + exe_.string() + ": " + std::strerror(err));
    // wait, polling, so that a SIGINT / SIGTERM sent to this process alone
    // reaches the run too (it then saves what it can and stops)
    int status = 0;
    rusage usage{};
    bool forwarded = false;
    for (;;) {
      const pid_t done = wait4(pid, &status, WNOHANG, &usage);
      if (done == pid) break;
      if (done < 0 && errno != EINTR)
        throw std::runtime_error(std::string("report: waiting for a run failed: ") + std::strerror(errno));
      if (const int sig = stop_requested(); sig && !forwarded) {
        kill(pid, sig);
        forwarded = true;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    r.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    r.cpu_seconds = double(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
                    1e-6 * double(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
    r.peak_memory_mb = double(usage.ru_maxrss) / 1024.0;
    const int sig = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + sig;
    r.stamp = std::to_string(std::chrono::system_clock::now().time_since_epoch().count()) + "-" + std::to_string(pid);
    const bool stopped = sig == SIGINT || sig == SIGTERM || r.exit_code == 130 || r.exit_code == 143 || stop_requested();
    r.status = r.exit_code == 0 ? "done" : stopped ? "interrupted" : "failed";
    io::write_json(record_file, r.json());  // a run that finished is kept even when a stop came meanwhile
    if (stopped)
      throw Interrupted(sig ? sig : (r.exit_code == 143 ? SIGTERM : SIGINT),
                        "report: stopped during " + job.title + "; finished runs are kept in " + work_.string() +
                            ": the same command goes on from there");
    return r;
  }

  fs::path work_;
  bool rerun_;
  fs::path exe_;
  std::string build_;
  std::map<std::string, JobRecord> records_;
};

}  // namespace difftrans::cli::report
