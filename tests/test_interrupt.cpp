// Signals that ask to stop: the first sets the flag work checks, a second ends the process, and
// the copy of one request that coreutils' timeout sends (the command, then its process group)
// counts once.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <functional>

#include "core/interrupt.hpp"

namespace linebake {
namespace {

// The status of a forked child that installs the handlers, runs `signals`, and exits 0 if it
// is still alive with SIGTERM as the signal that asked to stop.
int child_status(const std::function<void()>& signals) {
  const pid_t child = ::fork();
  if (child == 0) {
    install_interrupt_handlers();
    signals();
    ::_exit(interrupt_signal() == SIGTERM ? 0 : 1);
  }
  int status = -1;
  ::waitpid(child, &status, 0);
  return status;
}

TEST(Interrupt, OneRequestSentTwiceAtOnceStopsAtTheNextSafePoint) {
  const int status = child_status([] {
    ::kill(::getpid(), SIGTERM);
    ::kill(::getpid(), SIGTERM);
  });
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
}

TEST(Interrupt, ASecondSignalAfterASecondEndsTheProcess) {
  const int status = child_status([] {
    ::kill(::getpid(), SIGTERM);
    ::usleep(1'200'000);
    ::kill(::getpid(), SIGTERM);
    ::pause();  // not reached
  });
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM) << status;
}

TEST(Interrupt, ASecondSignalOfAnotherKindEndsTheProcess) {
  const int status = child_status([] {
    ::kill(::getpid(), SIGTERM);
    ::kill(::getpid(), SIGINT);
    ::pause();  // not reached
  });
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGINT) << status;
}

TEST(Interrupt, ASecondSignalFromAnotherProcessEndsTheProcess) {
  const int status = child_status([] {
    ::kill(::getpid(), SIGTERM);
    const pid_t me = ::getpid();
    const pid_t other = ::fork();
    if (other == 0) {
      ::kill(me, SIGTERM);
      ::_exit(0);
    }
    ::pause();  // the other process's signal ends this one
  });
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM) << status;
}

}  // namespace
}  // namespace linebake
