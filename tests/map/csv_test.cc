#include "areomap/map/csv.h"

#include <gtest/gtest.h>

namespace areomap {
namespace {

TEST(SplitCsvLine, KeepsEmptyInnerFieldsAndDropsACarriageReturn) {
  EXPECT_EQ(SplitCsvLine("a,,3.5"), (std::vector<std::string>{"a", "", "3.5"}));
  EXPECT_EQ(SplitCsvLine("x_px,y_px\r"), (std::vector<std::string>{"x_px", "y_px"}));
  EXPECT_EQ(SplitCsvLine(" id , name"), (std::vector<std::string>{" id ", " name"}));
  EXPECT_TRUE(SplitCsvLine("").empty());
}

}  // namespace
}  // namespace areomap
